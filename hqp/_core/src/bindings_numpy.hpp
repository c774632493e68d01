// NumPy arrays returned from the bindings without a Python-level copy.
//
// nanobind returns a small Eigen vector by value as a copy made through NumPy's Python API
// (about 1 us per array; a step returns a dozen); these helpers copy in C++ into a buffer the
// new array owns (a capsule).
#pragma once

#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <algorithm>
#include <cstddef>

namespace hqp {

/// A new NumPy array owning a copy of `n` values.
template <typename T>
nanobind::object to_numpy(const T* data, std::size_t n) {
  namespace nb = nanobind;
  T* buf = new T[n > 0 ? n : 1];
  std::copy(data, data + n, buf);
  nb::capsule owner(buf, [](void* q) noexcept { delete[] static_cast<T*>(q); });
  return nb::cast(nb::ndarray<nb::numpy, T, nb::ndim<1>>(buf, {n}, owner),
                  nb::rv_policy::reference);
}

/// A new NumPy array owning a copy of a (contiguous) vector.
template <typename Derived>
nanobind::object to_numpy(const Eigen::DenseBase<Derived>& v) {
  using Scalar = typename Derived::Scalar;
  static_assert(Derived::IsVectorAtCompileTime, "to_numpy: a vector");
  if (v.derived().innerStride() == 1) return to_numpy(v.derived().data(), std::size_t(v.size()));
  const Eigen::Matrix<Scalar, Eigen::Dynamic, 1> c = v;
  return to_numpy(c.data(), std::size_t(c.size()));
}

}  // namespace hqp
