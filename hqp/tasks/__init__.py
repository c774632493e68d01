"""Control primitives (the seed's Table 2), one per file."""

from hqp.tasks.base import Category, Rows, Task

__all__ = ["Category", "Rows", "Task"]
