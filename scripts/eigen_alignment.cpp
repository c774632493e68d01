// Which Eigen kernels of the solver's AVX2 units round differently with their data's
// alignment (docs/concepts/architecture.md, "Determinism"). Each kernel runs on the same
// values placed 0, 16, 32 and 48 bytes off a 64-byte boundary, and the bits of its result are
// compared. Built with the solver's flags:
//
//   g++ -O3 -DNDEBUG -mavx2 -mfma -DEIGEN_MAX_ALIGN_BYTES=16 -DEIGEN_MALLOC_ALREADY_ALIGNED=1 \
//       -I"$(python -m cmeel cmake)/include/eigen3" scripts/eigen_alignment.cpp -o eigen_alignment
//   ./eigen_alignment
#include <Eigen/Dense>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>

using namespace Eigen;

namespace {

unsigned long long digest(const double* p, int n, int stride = 1) {
  unsigned long long s = 1469598103934665603ULL;
  for (int i = 0; i < n; ++i) {
    unsigned long long b;
    std::memcpy(&b, p + i * stride, 8);
    s = (s ^ b) * 1099511628211ULL;
  }
  return s;
}

// One kernel on A (d, n), x (n), y (d), G (d, d) at an offset from a 64-byte boundary; the
// digest of every buffer it writes.
unsigned long long run(int op, int off, const MatrixXd& A0, const VectorXd& x0,
                       const VectorXd& y0) {
  const int d = int(A0.rows()), n = int(A0.cols());
  const std::size_t bytes = 64 * ((d * n + n + d + d * d) * 8 / 64 + 8);
  char* raw = static_cast<char*>(std::aligned_alloc(64, bytes + 256));
  double* a = reinterpret_cast<double*>(raw + off);
  double* x = a + (d * n + 7) / 8 * 8;
  double* y = x + (n + 7) / 8 * 8;
  double* g = y + (d + 7) / 8 * 8;
  Map<MatrixXd> A(a, d, n), G(g, d, d);
  Map<VectorXd> X(x, n), Y(y, d);
  A = A0;
  X = x0;
  Y = y0;
  G.noalias() = A * A.transpose();
  switch (op) {
    case 0: Y += 0.37 * A.col(3); break;
    case 1: Y.noalias() += A * X; break;
    case 2: X.noalias() -= A.transpose() * Y; break;
    case 3: { JacobiRotation<double> j(0.6, 0.8); A.applyOnTheRight(2, 5, j); break; }
    case 4: { JacobiRotation<double> j(0.6, 0.8); A.applyOnTheLeft(2, 5, j); break; }
    case 5: { double ws[64]; A.applyHouseholderOnTheLeft(A0.col(0).tail(d - 1), 0.7, ws); break; }
    case 6: A.leftCols(d).triangularView<Upper>().solveInPlace(Y); break;
    case 7: Y(0) = A.col(1).dot(A.col(2)); break;
    case 8: Y(0) = A.col(1).squaredNorm(); break;
    case 9: Y = Y.cwiseProduct(A.col(4)) + 0.3 * A.col(5); break;
    case 10: { LLT<Ref<MatrixXd>> llt(G); Y = llt.solve(Y); break; }
    case 11: { Map<VectorXd> h(x, d - 1); internal::tridiagonalization_inplace(G, h); break; }
  }
  const unsigned long long h = digest(a, d * n) ^ 3 * digest(x, n) ^ 7 * digest(y, d) ^
                               11 * digest(g, d * d);
  std::free(raw);
  return h;
}

}  // namespace

int main() {
  const char* names[] = {"axpy", "gemv", "gemv^T", "rotation right", "rotation left",
                         "householder", "triangular solve", "dot", "squared norm",
                         "element-wise", "cholesky", "tridiagonalisation"};
  for (int d : {6, 10, 17, 24, 40}) {
    const int n = d + 5;
    std::mt19937 gen(d);
    std::normal_distribution<double> normal;
    MatrixXd A0(d, n);
    VectorXd x0(n), y0(d);
    for (int i = 0; i < A0.size(); ++i) A0.data()[i] = normal(gen);
    for (int i = 0; i < n; ++i) x0(i) = normal(gen);
    for (int i = 0; i < d; ++i) y0(i) = normal(gen);
    for (int op = 0; op < 12; ++op) {
      const unsigned long long h0 = run(op, 0, A0, x0, y0);
      int differ = 0;
      for (int off : {16, 32, 48}) differ += run(op, off, A0, x0, y0) != h0;
      std::printf("d=%2d %-20s %s\n", d, names[op], differ ? "DIFFERS" : "same");
    }
  }
}
