// Small dense factorisations of the native solver (Eigen), the C++ twins of
// hqp/solver/linalg.py. Every object is a workspace of fixed capacity: reserved once for the
// largest shape it will see (reserve(), the only place that allocates), then recomputed in
// place on views of that storage, without heap allocation, whatever the shape of each call.
#pragma once

#include "solver/malloc_check.hpp"

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/SVD>

#include <cstdlib>
#include <cstring>
#include <new>
#include <utility>
#include <vector>

namespace hqp {

using Eigen::Index;
using Eigen::MatrixXd;
using Eigen::VectorXd;
using IVec = Eigen::VectorXi;
using MatRef = Eigen::Ref<MatrixXd>;
using CMatRef = Eigen::Ref<const MatrixXd>;
using VecRef = Eigen::Ref<VectorXd>;
using CVecRef = Eigen::Ref<const VectorXd>;
using IVecRef = Eigen::Ref<IVec>;
using MapM = Eigen::Map<MatrixXd>;
using CMapM = Eigen::Map<const MatrixXd>;
using MapV = Eigen::Map<VectorXd>;
using CMapV = Eigen::Map<const VectorXd>;
using MapI = Eigen::Map<IVec>;
using CMapI = Eigen::Map<const IVec>;

/// Whether Eigen may allocate on the heap (checked build only; no-op otherwise).
void set_malloc_allowed(bool allowed);

/// Storage of a matrix or vector of varying shape and bounded size: reserve() allocates
/// the capacity, then mat(rows, cols) / vec(size) view its first entries with that shape
/// (column-major, contiguous: the layout of a MatrixXd of that shape), without allocating.
/// A shape beyond the capacity grows the storage (an allocation, which the checked build
/// reports: a capacity computed too small is a bug, not a wrong result). Shaping does not
/// keep the entries (as Eigen's resize).
///
/// The storage starts on a kWorkAlign-byte boundary in every process: Eigen's kernels split
/// some sums where the data meets their packets' alignment (with AVX, the symmetric
/// matrix-vector product of the tridiagonalisation in TriangularSingularValues rounds
/// differently on a block 16 bytes off a 32-byte boundary), and malloc's blocks are only
/// 16-byte aligned, wherever the allocation history of the process puts them
/// (docs/concepts/architecture.md#determinism). The block comes from std::aligned_alloc and
/// goes back to std::free, which every translation unit may call, with AVX or without.
template <typename Scalar>
class Work {
 public:
  using Mat = Eigen::Matrix<Scalar, Eigen::Dynamic, Eigen::Dynamic>;
  using Vec = Eigen::Matrix<Scalar, Eigen::Dynamic, 1>;
  static constexpr std::size_t kWorkAlign = 64;

  Work() = default;
  Work(const Work& other) { *this = other; }
  Work(Work&& other) noexcept { swap(other); }
  Work& operator=(const Work& other) {
    if (this != &other) {
      reserve(other.cap_);
      if (other.cap_) std::memcpy(buf_, other.buf_, sizeof(Scalar) * other.cap_);
      rows_ = other.rows_;
      cols_ = other.cols_;
    }
    return *this;
  }
  Work& operator=(Work&& other) noexcept {
    if (this != &other) {
      Work gone(std::move(other));
      swap(gone);
    }
    return *this;
  }
  ~Work() { std::free(buf_); }

  void reserve(Index size) {
    if (size <= cap_) return;
    // an allocation: the checked build's run-time check sees it, as Eigen's own
    Eigen::internal::check_that_malloc_is_allowed();
    const std::size_t bytes = sizeof(Scalar) * static_cast<std::size_t>(size);
    const std::size_t rounded = (bytes + kWorkAlign - 1) / kWorkAlign * kWorkAlign;
    void* block = std::aligned_alloc(kWorkAlign, rounded);
    if (!block) throw std::bad_alloc();
    std::free(buf_);
    buf_ = static_cast<Scalar*>(block);
    cap_ = size;
  }
  void reserve(Index rows, Index cols) { reserve(rows * cols); }
  Index capacity() const { return cap_; }

  Eigen::Map<Mat> mat(Index rows, Index cols) {
    reserve(rows * cols);
    rows_ = rows;
    cols_ = cols;
    return Eigen::Map<Mat>(buf_, rows, cols);
  }
  Eigen::Map<Vec> vec(Index size) {
    reserve(size);
    rows_ = size;
    cols_ = 1;
    return Eigen::Map<Vec>(buf_, size);
  }
  /// The last shape given.
  Eigen::Map<Mat> mat() { return Eigen::Map<Mat>(buf_, rows_, cols_); }
  Eigen::Map<const Mat> mat() const { return Eigen::Map<const Mat>(buf_, rows_, cols_); }
  Eigen::Map<Vec> vec() { return Eigen::Map<Vec>(buf_, rows_ * cols_); }
  Eigen::Map<const Vec> vec() const { return Eigen::Map<const Vec>(buf_, rows_ * cols_); }
  Index rows() const { return rows_; }
  Index cols() const { return cols_; }
  Index size() const { return rows_ * cols_; }
  Scalar* data() { return buf_; }

 private:
  void swap(Work& other) noexcept {
    std::swap(buf_, other.buf_);
    std::swap(cap_, other.cap_);
    std::swap(rows_, other.rows_);
    std::swap(cols_, other.cols_);
  }
  Scalar* buf_ = nullptr;
  Index cap_ = 0;
  Index rows_ = 0, cols_ = 0;
};

using WorkM = Work<double>;
using WorkI = Work<int>;

/// Where the nonzero entries of a matrix's rows lie (M (m, c)), for products M Z with a
/// dense Z (c, r) that skip the zero columns: consecutive rows whose nonzero entries span the
/// same columns form a block (a product of that block with those rows of Z), consecutive
/// rows of one nonzero entry each a gather block (each row a scaled row of Z). Task rows are
/// mostly so: a posture or joint-limit row selects one joint, a contact limit touches its
/// contact's force, a frame task the accelerations and not the forces. The result is M Z
/// up to the summation order of its nonzero terms (rounding).
class RowSupport {
 public:
  void reserve(Index m) {
    blocks_.reserve(std::size_t(m) + 1);
    col_.reserve(m);
    last_.reserve(m);
  }
  /// Scan M (called when M's entries change; allocates only beyond reserve(M.rows())).
  void compute(const CMatRef& M);
  /// out (m, r) = M Z for Z (c, r); M as given to compute().
  void project(const CMatRef& M, const CMapM& Z, MapM out) const;
  Index blocks() const { return Index(blocks_.size()); }

 private:
  struct Block {
    Index r0, nr, c0, nc;
    bool gather;
  };
  std::vector<Block> blocks_;
  WorkI col_;   // each row's first nonzero column (a gather row's one nonzero entry)
  WorkI last_;  // each row's last nonzero column
};

/// Householder QR with column pivoting A P = Q R, in place on fixed-capacity storage: the
/// steps of Eigen's ColPivHouseholderQR::computeInPlace (the same Householder and norm
/// downdating calls, in the same order), whose members Eigen resizes at each new shape.
class ColPivQR {
 public:
  void reserve(Index rows, Index cols);
  /// Shape the matrix to factor (rows, cols); fill it, then factor().
  MapM input(Index rows, Index cols) { return qr_.mat(rows, cols); }
  void factor();
  CMapM matrixQR() const { return qr_.mat(); }
  CMapV hCoeffs() const { return hc_.vec(); }
  /// The original column of pivoted column i.
  int perm(Index i) const { return perm_.vec()(i); }

 private:
  WorkM qr_, hc_, temp_, nu_, nd_;  // temp_: Householder workspace; nu_, nd_: column norms
  WorkI perm_;
};

/// Singular values of a matrix T (d, c), d <= c, largest first: eigenvalues of T T^T
/// (tridiagonal QR, O(d^3) once), and a Jacobi SVD of T only where the smallest is below
/// 1e-6 of the largest (where squaring would lose its digits: eps * s_max^2 / s_min).
/// Both run Eigen's algorithms (SelfAdjointEigenSolver, eigenvalues only; JacobiSVD with
/// its column-pivoting QR preconditioner, singular values only) on this object's storage.
class TriangularSingularValues {
 public:
  void reserve(Index d, Index c);
  /// `rank_tol`, `scale`: a square triangular T whose smallest diagonal entry is at most
  /// rank_tol * max(s_max, scale) has s_min below that threshold too (s_min <= min |T_ii|):
  /// s(d-1) is then set to 0 without the Jacobi SVD (the rank decision the caller makes).
  void compute(const CMatRef& T, VecRef s, double rank_tol = 0.0, double scale = 0.0);

 private:
  /// Eigenvalues of the symmetric G_ (lower triangle read), ascending, into diag_; false
  /// where the QR iteration did not converge.
  bool eigenvalues(Index d);
  /// Singular values of T, descending, into s (Eigen's JacobiSVD).
  void jacobi(const CMatRef& T, VecRef s);
  WorkM G_, diag_, sub_, hc_, work_;
  ColPivQR pre_;
};

/// Rank-revealing QR of a matrix M (m, r) through M^T P = Q R (column pivoting on M^T, i.e.
/// on the rows of M, as LAPACK's dgeqp3 in the Python reference).
///
/// Rank: the number of |R_ii| above rank_tol * max(|R_00|, scale).
///
/// Q is applied as its first `rank` reflectors Q' = H_0 ... H_{rank-1}: the later ones leave
/// Q's first rank columns (the range of M^T) unchanged, so Q' has the same first columns and
/// its others span the same null space (another orthonormal basis of it).
class PivotedQR {
 public:
  /// Capacity for M up to (m, r); `right_rows`: the rows of the matrices given to
  /// apply_q_right.
  void reserve(Index m, Index r, Index right_rows = 0);
  /// Factorise M. `scale`: the largest entry of the level's unprojected rows (0 if none).
  void compute(const CMatRef& M, double rank_tol, double scale);
  /// Factorise with the rank relative to |R_00| alone (the active-set solves).
  void compute_relative(const CMatRef& M, double rank_tol);

  Index rank() const { return rank_; }
  Index rows() const { return m_; }  ///< m
  Index cols() const { return r_; }  ///< r
  /// Orthonormal basis (r, r - rank) of the null space of M: Q's trailing columns, formed
  /// from the reflectors alone.
  CMapM null();
  /// v := Q v and v := Q^T v for v (r,).
  void apply_q(VecRef v);
  void apply_qt(VecRef v);
  /// A := A Q for A (rows, r).
  void apply_q_right(MatRef A);
  /// Least-squares solution y (r,) of M y ~ rhs, minimum norm up to the rank cut.
  void lstsq(const CVecRef& rhs, VecRef y);
  /// y (r,) = Q1 R11^-T k[piv[:rank]] (the minimum-norm point of the first `rank` pivoted
  /// rows of M held at k; the active-set solves).
  void particular(const CVecRef& k, VecRef y);
  /// mu[piv[:rank]] = R11^-1 c for c (rank,) (multipliers of the held rows).
  void multipliers(const CVecRef& c, VecRef mu);
  /// Index of the i-th pivoted row of M.
  Index pivot(Index i) const { return qr_.perm(i); }
  /// Singular values of M (those of R), largest first, into s (min(m, r),).
  void singular_values(VecRef s, double rank_tol = 0.0, double scale = 0.0);

 private:
  void factor(const CMatRef& M);
  ColPivQR qr_;   // of M^T (r, m)
  ColPivQR lqr_;  // of the trapezoid L (m, rank) in lstsq
  WorkM N_, Rsq_, ws_, wsn_, wsr_, z_, c_;  // ws_, wsn_, wsr_: Householder workspaces
  TriangularSingularValues sv_;
  Index m_ = 0, r_ = 0, rank_ = 0;
  bool n_ready_ = false;
};


/// The filter of a level's weak directions (the C++ twin of hqp.solver.linalg.weak_filter):
/// the target component along each left singular vector of M (m, r) whose singular value s
/// lies below `threshold` is scaled by (s / threshold)^2. From the eigen-decomposition of
/// M M^T by cyclic Jacobi rotations (m is a task's few rows; accurate to eps * ||M||^2 in
/// s^2, as LAPACK's dsyevd of the Python reference), on this object's storage.
/// hqp.solver.linalg.WEAK_COUNT_FLOOR: singular values below it (relative), as s^2 from
/// M M^T, cannot be told from 0.
constexpr double kWeakCountFloor = 1e-7;

class WeakFilter {
 public:
  void reserve(Index m, Index r);
  /// Filter rhs = b - A x0 (m,) in place, M = A Z; returns the number of weak directions
  /// above max(rank_tol, kWeakCountFloor) * max(s_max, scale). The weak components are
  /// measured at the minimum-norm point x0 - Z Z^T x0 of the optimal set above (`Z`
  /// nullptr: the identity, that point is 0 and the target b), as weak_filter's `centred`.
  int apply(const CMatRef& M, VecRef rhs, const CMapM* Z, const CVecRef& x0,
            const CVecRef& b, double threshold, double rank_tol, double scale);

 private:
  WorkM G_, V_, z_, c_;
};

/// Minimum-norm least squares of M y ~ rhs (the C++ twin of hqp.solver.linalg.lstsq):
/// pivoted QR with the threshold rank_tol * max(|R_00|, scale).
class LeastSquares {
 public:
  void reserve(Index m, Index r) { qr_.reserve(m, r); }
  void solve(const CMatRef& M, const CVecRef& rhs, double rank_tol, double scale, VecRef y);

 private:
  PivotedQR qr_;
};

/// Singular values of M (m, r), m <= r, largest first: those of the (m, m) triangular
/// factor of M^T.
class SingularValues {
 public:
  void reserve(Index m, Index r);
  CMapV compute(const CMatRef& M, double rank_tol = 0.0, double scale = 0.0);

 private:
  ColPivQR qr_;
  WorkM R_, s_;
  TriangularSingularValues sv_;
};

}  // namespace hqp
