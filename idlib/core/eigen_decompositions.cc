// The one instantiation of Eigen's decompositions that lpvid uses (see the header).
#include "idlib/core/eigen_decompositions.h"

LPVID_EIGEN_DECOMPOSITIONS()
