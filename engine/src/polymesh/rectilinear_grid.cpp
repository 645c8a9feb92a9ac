#include "polymesh/rectilinear_grid.hpp"

#include <vfe/error.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace vfe {

RectilinearGrid::RectilinearGrid(std::array<std::vector<double>, 3> nodes) : nodes_(std::move(nodes)) {
  const char* axis = "xyz";
  for (int d = 0; d < 3; ++d) {
    const auto& x = nodes_[static_cast<std::size_t>(d)];
    std::ostringstream msg;
    if (x.size() < 2) {
      msg << "rectilinear grid axis " << axis[d] << " has " << x.size()
          << " node coordinates; give at least 2 (one cell has a lower and an upper node)";
      throw Error(VFE_ERROR_INVALID_ARGUMENT, msg.str());
    }
    for (std::size_t i = 0; i < x.size(); ++i) {
      if (!std::isfinite(x[i])) {
        msg << "rectilinear grid axis " << axis[d] << ": node " << i << " is " << x[i] << "; give finite coordinates";
        throw Error(VFE_ERROR_INVALID_ARGUMENT, msg.str());
      }
      if (i > 0 && !(x[i] > x[i - 1])) {
        msg << "rectilinear grid axis " << axis[d] << ": node " << i << " (" << x[i] << ") is not greater than node "
            << i - 1 << " (" << x[i - 1] << "); give strictly increasing coordinates";
        throw Error(VFE_ERROR_INVALID_ARGUMENT, msg.str());
      }
    }
    n_[static_cast<std::size_t>(d)] = static_cast<std::int64_t>(x.size()) - 1;
  }
  // As for Cartesian grids: every cell volume and its inverse must be normal doubles
  // (node gaps of 1e-200 give volumes of 0 and void fractions of NaN).
  double smallest = 1, largest = 1;
  for (const auto& x : nodes_) {
    double lo = x[1] - x[0], hi = lo;
    for (std::size_t i = 1; i < x.size(); ++i) {
      lo = std::min(lo, x[i] - x[i - 1]);
      hi = std::max(hi, x[i] - x[i - 1]);
    }
    smallest *= lo;
    largest *= hi;
  }
  if (!std::isnormal(smallest) || !std::isnormal(1.0 / smallest) || !std::isfinite(largest)) {
    std::ostringstream msg;
    msg << "rectilinear grid cells range from " << smallest << " to " << largest
        << " in volume, which cannot be computed in doubles (each cell volume and its inverse must lie within "
        << std::numeric_limits<double>::min() << " .. " << std::numeric_limits<double>::max()
        << "); give the nodes in units where cells are nearer to 1 (e.g. mm or m)";
    throw Error(VFE_ERROR_INVALID_ARGUMENT, msg.str());
  }
  for (int d = 0; d < 3; ++d) {
    const auto k = static_cast<std::size_t>(d);
    const auto& x = nodes_[k];
    // About four buckets a cell (at most 2^22 an axis).
    bucket_last_[k] = static_cast<std::size_t>(std::min<std::int64_t>(4 * n_[k], std::int64_t(1) << 22));
    bucket_scale_[k] = double(bucket_last_[k]) / (x.back() - x.front());
    auto& first = bucket_first_[k];
    first.assign(bucket_last_[k] + 2, 0);
    for (const double v : x) ++first[bucket(d, v) + 1];  // nodes per bucket, one slot up
    for (std::size_t b = 1; b < first.size(); ++b) first[b] += first[b - 1];
  }
  const double total = double(n_[0]) * double(n_[1]) * double(n_[2]);
  if (total > double(std::int64_t(1) << 40)) {
    std::ostringstream msg;
    msg << "rectilinear grid of " << n_[0] << " x " << n_[1] << " x " << n_[2] << " cells is too large (limit 2^40 cells); "
        << "use fewer nodes";
    throw Error(VFE_ERROR_INVALID_ARGUMENT, msg.str());
  }
}

std::int64_t RectilinearGrid::axis_index(int d, double x) const {
  const auto& nodes = nodes_[static_cast<std::size_t>(d)];
  // First node greater than x; x_i <= x < x_{i+1} for i = that - 1. NaN compares false
  // everywhere and lands below the grid.
  if (!(x >= nodes.front())) return -1;
  const std::size_t b = bucket(d, x);
  const auto& first = bucket_first_[static_cast<std::size_t>(d)];
  const auto it = std::upper_bound(nodes.begin() + first[b], nodes.begin() + first[b + 1], x);
  return static_cast<std::int64_t>(it - nodes.begin()) - 1;
}

std::int64_t RectilinearGrid::locate(const Eigen::Vector3d& p) const {
  std::int64_t ijk[3];
  for (int d = 0; d < 3; ++d) {
    ijk[d] = axis_index(d, p[d]);
    if (ijk[d] < 0 || ijk[d] >= n_[static_cast<std::size_t>(d)]) return -1;
  }
  return index(ijk[0], ijk[1], ijk[2]);
}

std::int64_t RectilinearGrid::nearest(const Eigen::Vector3d& p) const {
  std::int64_t ijk[3];
  for (int d = 0; d < 3; ++d) ijk[d] = std::clamp<std::int64_t>(axis_index(d, p[d]), 0, n_[static_cast<std::size_t>(d)] - 1);
  return index(ijk[0], ijk[1], ijk[2]);
}

double RectilinearGrid::cell_volume(std::int64_t c) const {
  const auto [i, j, k] = ijk(c);
  return (nodes_[0][static_cast<std::size_t>(i) + 1] - nodes_[0][static_cast<std::size_t>(i)]) *
         (nodes_[1][static_cast<std::size_t>(j) + 1] - nodes_[1][static_cast<std::size_t>(j)]) *
         (nodes_[2][static_cast<std::size_t>(k) + 1] - nodes_[2][static_cast<std::size_t>(k)]);
}

Eigen::Vector3d RectilinearGrid::cell_centre(std::int64_t c) const {
  const auto idx = ijk(c);
  Eigen::Vector3d centre;
  for (int d = 0; d < 3; ++d) {
    const auto i = static_cast<std::size_t>(idx[static_cast<std::size_t>(d)]);
    centre[d] = 0.5 * (nodes_[static_cast<std::size_t>(d)][i] + nodes_[static_cast<std::size_t>(d)][i + 1]);
  }
  return centre;
}

std::vector<double> RectilinearGrid::cell_volumes() const {
  std::vector<double> v(static_cast<std::size_t>(cell_count()));
  for (std::int64_t c = 0; c < cell_count(); ++c) v[static_cast<std::size_t>(c)] = cell_volume(c);
  return v;
}

PolyMeshData RectilinearGrid::polymesh_data() const {
  const std::int64_t nx = n_[0], ny = n_[1], nz = n_[2];
  PolyMeshData m;
  m.source = "rectilinear grid";
  m.points.reserve(static_cast<std::size_t>((nx + 1) * (ny + 1) * (nz + 1)));
  for (std::int64_t k = 0; k <= nz; ++k)
    for (std::int64_t j = 0; j <= ny; ++j)
      for (std::int64_t i = 0; i <= nx; ++i) m.points.emplace_back(nodes_[0][i], nodes_[1][j], nodes_[2][k]);
  auto point = [&](std::int64_t i, std::int64_t j, std::int64_t k) { return i + (nx + 1) * (j + (ny + 1) * k); };
  // The face of cell (i, j, k) on its upper side along axis d, its points ordered so that
  // the right-hand normal points towards +d (reversed: towards -d).
  auto add_face = [&](int d, std::int64_t i, std::int64_t j, std::int64_t k, bool towards_minus) {
    std::int64_t q[4];
    if (d == 0) {
      q[0] = point(i + 1, j, k), q[1] = point(i + 1, j + 1, k), q[2] = point(i + 1, j + 1, k + 1),
      q[3] = point(i + 1, j, k + 1);
    } else if (d == 1) {
      q[0] = point(i, j + 1, k), q[1] = point(i, j + 1, k + 1), q[2] = point(i + 1, j + 1, k + 1),
      q[3] = point(i + 1, j + 1, k);
    } else {
      q[0] = point(i, j, k + 1), q[1] = point(i + 1, j, k + 1), q[2] = point(i + 1, j + 1, k + 1),
      q[3] = point(i, j + 1, k + 1);
    }
    if (towards_minus) std::swap(q[1], q[3]);
    m.face_points.insert(m.face_points.end(), q, q + 4);
    m.face_offsets.push_back(static_cast<std::int64_t>(m.face_points.size()));
  };
  // Internal faces: by owner, then by neighbour (c + 1, c + nx, c + nx * ny increase).
  for (std::int64_t k = 0; k < nz; ++k)
    for (std::int64_t j = 0; j < ny; ++j)
      for (std::int64_t i = 0; i < nx; ++i) {
        const std::int64_t c = index(i, j, k);
        const bool up[3] = {i + 1 < nx, j + 1 < ny, k + 1 < nz};
        const std::int64_t next[3] = {c + 1, c + nx, c + nx * ny};
        for (int d = 0; d < 3; ++d) {
          if (!up[d]) continue;
          add_face(d, i, j, k, false);
          m.owner.push_back(c);
          m.neighbour.push_back(next[d]);
        }
      }
  // Boundary patches, each face pointing out of the grid.
  const char* names[6] = {"xmin", "xmax", "ymin", "ymax", "zmin", "zmax"};
  for (int side = 0; side < 6; ++side) {
    const int d = side / 2;
    const bool upper = side % 2 == 1;
    PolyPatch patch{names[side], "patch", m.face_count(), 0, {}, false};
    for (std::int64_t k = 0; k < nz; ++k)
      for (std::int64_t j = 0; j < ny; ++j)
        for (std::int64_t i = 0; i < nx; ++i) {
          const std::int64_t at[3] = {i, j, k};
          if (at[d] != (upper ? n_[d] - 1 : 0)) continue;
          // A lower face is the upper face of the cell below, pointing towards -d.
          std::int64_t b[3] = {i, j, k};
          if (!upper) --b[d];
          add_face(d, b[0], b[1], b[2], !upper);
          m.owner.push_back(index(i, j, k));
          ++patch.n_faces;
        }
    m.patches.push_back(patch);
  }
  return m;
}

}  // namespace vfe
