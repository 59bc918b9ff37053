// Eigen's dense decompositions, compiled once: explicit instantiation declarations
// for the decompositions lpvid uses on dynamic double and complex matrices, defined in
// idlib/core/eigen_decompositions.cc (idlib_core, which everything links).
//
// Why: Eigen 3.4's decompositions are templates that every translation unit using
// them instantiates and compiles anew.  Measured with gcc 12 -O0 (front end only, user
// CPU, a one-function file): BDCSVD<MatrixXd> 48.5 s, JacobiSVD<MatrixXd> 12.7 s,
// EigenSolver<MatrixXd> 20.9 s, against 2.3 s for the headers alone; with these
// declarations that one-function file using BDCSVD or JacobiSVD compiles in 3.1 s at
// -O2 (docs/dev/CI.md).  Include this before the first use (it includes Eigen/Dense), in
// every file that uses one of them (a file that does not still compiles and links; it
// only pays again).
//
// Covered: the class templates below whole, and compute() of the eigen and Schur
// solvers on a plain matrix (their compute is a member template: a call on an
// expression, e.g. es(A + A.transpose()), still instantiates its own copy).
#pragma once

#include <Eigen/Dense>

#define LPVID_EIGEN_DECOMPOSITIONS(EXTERN)                                                                            \
  EXTERN template class Eigen::JacobiSVD<Eigen::MatrixXd>;                                                           \
  EXTERN template class Eigen::JacobiSVD<Eigen::MatrixXcd>;                                                          \
  EXTERN template class Eigen::BDCSVD<Eigen::MatrixXd>;                                                              \
  EXTERN template class Eigen::FullPivLU<Eigen::MatrixXd>;                                                           \
  EXTERN template class Eigen::FullPivLU<Eigen::MatrixXcd>;                                                          \
  EXTERN template class Eigen::PartialPivLU<Eigen::MatrixXd>;                                                        \
  EXTERN template class Eigen::PartialPivLU<Eigen::MatrixXcd>;                                                       \
  EXTERN template class Eigen::ColPivHouseholderQR<Eigen::MatrixXd>;                                                 \
  EXTERN template class Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>;                                     \
  EXTERN template Eigen::EigenSolver<Eigen::MatrixXd>& Eigen::EigenSolver<Eigen::MatrixXd>::compute<Eigen::MatrixXd>( \
      const Eigen::EigenBase<Eigen::MatrixXd>&, bool);                                                               \
  EXTERN template Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>&                                                    \
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>::compute<Eigen::MatrixXd>(const Eigen::EigenBase<Eigen::MatrixXd>&, \
                                                                           int);                                     \
  EXTERN template Eigen::ComplexEigenSolver<Eigen::MatrixXcd>&                                                       \
  Eigen::ComplexEigenSolver<Eigen::MatrixXcd>::compute<Eigen::MatrixXcd>(const Eigen::EigenBase<Eigen::MatrixXcd>&,  \
                                                                         bool);                                      \
  EXTERN template Eigen::RealSchur<Eigen::MatrixXd>& Eigen::RealSchur<Eigen::MatrixXd>::compute<Eigen::MatrixXd>(     \
      const Eigen::EigenBase<Eigen::MatrixXd>&, bool);                                                               \
  EXTERN template Eigen::ComplexSchur<Eigen::MatrixXd>& Eigen::ComplexSchur<Eigen::MatrixXd>::compute<Eigen::MatrixXd>( \
      const Eigen::EigenBase<Eigen::MatrixXd>&, bool);

LPVID_EIGEN_DECOMPOSITIONS(extern)
