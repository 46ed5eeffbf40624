// Principal curvatures and directions per face, for curvature-aligned fields.
//
// Estimator (Rusinkiewicz 2004, per face, then smoothed): vertex normals are angle-weighted averages of
// face normals. In each face the shape operator II (2x2, symmetric, in the face frame) is the least-squares
// fit of II (e.x, e.y) = (dN.x, dN.y) over the three edges e with normal differences dN. Each face's
// tensor is then averaged, area-weighted, with the tensors of the faces sharing a vertex with it (re-
// expressed in its frame), which removes the noise of single-face estimates. Eigen-decomposition gives
// the principal curvatures (1/length; positive where the surface bends away from its normal, e.g. 1/R
// on a sphere with outward normals) and directions.
// kmax is the principal curvature of larger ABSOLUTE value (strongest bending), kmin the other one.
#pragma once
#include <Eigen/Core>
#include <vector>

#include "nfield/operators.hpp"

namespace nfield {

struct PrincipalCurvature {
  Eigen::VectorXd kmax, kmin;                  ///< per face (0 on inactive faces)
  std::vector<Eigen::Vector3d> dir_max, dir_min;  ///< unit tangent directions per face (0 on inactive)
};

PrincipalCurvature principal_curvature(const TriangleMesh& mesh, const TangentFrames& frames);

/// Alignment field for symmetry n along the max (or min) principal direction: per face
/// z = |kmax - kmin| sqrt(total_area) exp(i n theta) — the magnitude (dimensionless anisotropy) makes
/// umbilic and flat regions follow smoothness only. Throws ParameterError for odd n (principal
/// directions are lines, which a field with odd symmetry cannot represent).
ComplexVector curvature_alignment(const FieldOperators& ops, bool maximal);

}  // namespace nfield
