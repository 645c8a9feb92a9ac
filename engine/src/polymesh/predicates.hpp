// Exact geometric signs for point location: orientation of four points in 3D, decided
// exactly (a floating-point filter, then exact expansion arithmetic when the filter is
// unsure), with a symbolic displacement of the query point that breaks every tie the
// same way everywhere.
#pragma once

#include <Eigen/Core>

namespace vfe::geom {

/// det[b - a, c - a, d - a] = ((b - a) x (c - a)) . (d - a), six times the signed volume
/// of the tetrahedron abcd; positive when d lies on the side that the right-hand normal of
/// triangle abc points to. Plain floating point (may be wrong in sign near zero).
inline double orient3d_approx(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                              const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
  return (b - a).cross(c - a).dot(d - a);
}

/// Exact sign (-1, 0, +1) of orient3d(a, b, c, d) for finite inputs.
int orient3d_exact(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                   const Eigen::Vector3d& d);

namespace detail {
/// orient3d_sos when the floating-point filter cannot decide (exact arithmetic).
int orient3d_sos_exact(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                       const Eigen::Vector3d& d);
// Shewchuk's o3derrboundA, doubled as a margin for compilers that fuse multiply-adds.
inline constexpr double kOrient3dBound = 2.0 * (7.0 + 56.0 * 0x1p-53) * 0x1p-53;
}  // namespace detail

/// Exact sign of orient3d(a, b, c, d') where d' = d + (e, e^2, e^3) for an infinitesimal
/// e > 0 (simulation of simplicity on the query point only). When d lies exactly in the
/// plane of abc the sign is that of the plane normal n = (b - a) x (c - a) along x, or
/// along y if n_x = 0, or along z if n_x = n_y = 0: d goes to the side the +x (then +y,
/// then +z) direction points to. Returns 0 only when a, b, c are collinear (no plane).
/// Consistent by construction: any permutation of (a, b, c) gives the permuted sign, so
/// two cells that test the same plane never both claim, or both reject, a point.
/// Cost: one floating-point determinant with an error bound; exact arithmetic only when
/// d is within rounding distance of the plane.
inline int orient3d_sos(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                        const Eigen::Vector3d& d) {
  // Shewchuk's orient3d filter on det[a - d, b - d, c - d], which is -orient3d(a, b, c, d).
  const double adx = a.x() - d.x(), bdx = b.x() - d.x(), cdx = c.x() - d.x();
  const double ady = a.y() - d.y(), bdy = b.y() - d.y(), cdy = c.y() - d.y();
  const double adz = a.z() - d.z(), bdz = b.z() - d.z(), cdz = c.z() - d.z();
  const double bdxcdy = bdx * cdy, cdxbdy = cdx * bdy;
  const double cdxady = cdx * ady, adxcdy = adx * cdy;
  const double adxbdy = adx * bdy, bdxady = bdx * ady;
  const double det = adz * (bdxcdy - cdxbdy) + bdz * (cdxady - adxcdy) + cdz * (adxbdy - bdxady);
  const double permanent = ((bdxcdy < 0 ? -bdxcdy : bdxcdy) + (cdxbdy < 0 ? -cdxbdy : cdxbdy)) * (adz < 0 ? -adz : adz) +
                           ((cdxady < 0 ? -cdxady : cdxady) + (adxcdy < 0 ? -adxcdy : adxcdy)) * (bdz < 0 ? -bdz : bdz) +
                           ((adxbdy < 0 ? -adxbdy : adxbdy) + (bdxady < 0 ? -bdxady : bdxady)) * (cdz < 0 ? -cdz : cdz);
  const double bound = detail::kOrient3dBound * permanent;
  if (det > bound) return -1;
  if (-det > bound) return 1;
  return detail::orient3d_sos_exact(a, b, c, d);
}

}  // namespace vfe::geom
