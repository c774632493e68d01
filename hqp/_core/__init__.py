"""hqp's native core (C++17, compiled by the package build)."""
