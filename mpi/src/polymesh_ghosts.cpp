#include "polymesh_ghosts.hpp"

#include <vfe/error.hpp>

#include <algorithm>
#include <array>
#include <cstdlib>
#include <limits>
#include <string>
#include <unordered_map>

namespace vfe::mpi {

namespace {

using Box6 = std::array<double, 6>;  // lo x, y, z, hi x, y, z

void fail(const std::string& what) { throw Error(VFE_ERROR_INVALID_ARGUMENT, "decomposed polyMesh: " + what); }

bool meet(const double* a, const double* b) {
  for (int d = 0; d < 3; ++d)
    if (a[d] > b[3 + d] || b[d] > a[3 + d]) return false;
  return true;
}

Box6 widened(const double* b, double w) { return {b[0] - w, b[1] - w, b[2] - w, b[3] + w, b[4] + w, b[5] + w}; }

// OpenFOAM's face::reverseFace: the first point stays, the others run backwards (the
// reversal decomposePar applies to a processor face the global neighbour owns).
template <class It>
void reverse_face(It first, It last) {
  if (last - first > 2) std::reverse(first + 1, last);
}

// A face of the local mesh under construction, in the global mesh's orientation.
struct FaceEntry {
  std::vector<std::int64_t> points;  // local point indices
  std::int64_t owner = -1, neighbour = -1;  // local cells on the global owner's and neighbour's side
  bool global_boundary = false;              // a boundary face of the undecomposed mesh
  std::int64_t global_id = -1;               // the face in the undecomposed mesh
};

int as_int(std::size_t n) {
  if (n > static_cast<std::size_t>(std::numeric_limits<int>::max()))
    throw Error(VFE_ERROR_UNSUPPORTED, "a ghost message exceeds 2^31 values; decompose over more ranks");
  return static_cast<int>(n);
}

}  // namespace

std::int64_t RankPolyMesh::cell_count() const { return static_cast<std::int64_t>(cell_ids.size()); }

void check_rank_mesh(const RankPolyMesh& m) {
  const std::size_t points = m.mesh.points.size() / 3, faces = m.mesh.owner.size();
  std::int64_t cells = 0;
  for (const std::int64_t c : m.mesh.owner) cells = std::max(cells, c + 1);
  if (m.point_ids.size() != points)
    fail("there are " + std::to_string(m.point_ids.size()) + " global point ids for " + std::to_string(points) +
         " points; give one per point (pointProcAddressing)");
  if (m.face_ids.size() != faces)
    fail("there are " + std::to_string(m.face_ids.size()) + " global face ids for " + std::to_string(faces) +
         " faces; give one per face (faceProcAddressing)");
  if (static_cast<std::int64_t>(m.cell_ids.size()) != cells)
    fail("there are " + std::to_string(m.cell_ids.size()) + " global cell ids for " + std::to_string(cells) +
         " cells; give one per cell (cellProcAddressing)");
  if (m.coupled.size() != faces) fail("the coupled-face flags must have one entry per face");
  for (std::size_t f = 0; f < faces; ++f)
    if (m.face_ids[f] == 0)
      fail("face " + std::to_string(f) + " has global id 0; face ids are global face + 1, negated for a reversed face");
  for (const std::int64_t p : m.point_ids)
    if (p < 0) fail("a global point id is negative (" + std::to_string(p) + ")");
  for (const std::int64_t c : m.cell_ids)
    if (c < 0) fail("a global cell id is negative (" + std::to_string(c) + ")");
}

std::vector<double> cell_boxes(const RankPolyMesh& m) {
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> boxes(static_cast<std::size_t>(6 * m.cell_count()));
  for (std::size_t c = 0; c < boxes.size() / 6; ++c) std::copy_n(Box6{inf, inf, inf, -inf, -inf, -inf}.data(), 6, &boxes[6 * c]);
  const PolyMeshBuffers& b = m.mesh;
  auto grow = [&](std::int64_t cell, std::int64_t point) {
    double* box = &boxes[static_cast<std::size_t>(6 * cell)];
    for (int d = 0; d < 3; ++d) {
      const double x = b.points[static_cast<std::size_t>(3 * point + d)];
      box[d] = std::min(box[d], x);
      box[3 + d] = std::max(box[3 + d], x);
    }
  };
  for (std::size_t f = 0; f < b.owner.size(); ++f)
    for (std::int64_t i = b.face_offsets[f]; i < b.face_offsets[f + 1]; ++i) {
      grow(b.owner[f], b.face_points[static_cast<std::size_t>(i)]);
      if (f < b.neighbour.size()) grow(b.neighbour[f], b.face_points[static_cast<std::size_t>(i)]);
    }
  return boxes;
}

GhostedPolyMesh build_ghosted(MPI_Comm comm, const RankPolyMesh& m, const std::vector<double>& boxes, double width) {
  int rank = 0, size = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  const PolyMeshBuffers& b = m.mesh;
  const std::int64_t n_cells = m.cell_count();

  // 1. Every rank's bounding box (6 doubles each), and the candidates: ranks whose box comes
  //    within `width` of this one's (a symmetric relation).
  const double inf = std::numeric_limits<double>::infinity();
  Box6 mine{inf, inf, inf, -inf, -inf, -inf};
  for (std::int64_t c = 0; c < n_cells; ++c)
    for (int d = 0; d < 3; ++d) {
      mine[d] = std::min(mine[d], boxes[static_cast<std::size_t>(6 * c + d)]);
      mine[3 + d] = std::max(mine[3 + d], boxes[static_cast<std::size_t>(6 * c + 3 + d)]);
    }
  std::vector<double> all(static_cast<std::size_t>(6 * size));
  MPI_Allgather(mine.data(), 6, MPI_DOUBLE, all.data(), 6, MPI_DOUBLE, comm);
  const Box6 mine_wide = widened(mine.data(), width);
  std::vector<int> candidates;
  for (int q = 0; q < size; ++q)
    if (q != rank && n_cells > 0 && meet(mine_wide.data(), &all[static_cast<std::size_t>(6 * q)])) candidates.push_back(q);
  const int degree = static_cast<int>(candidates.size());
  MPI_Comm graph = MPI_COMM_NULL;
  MPI_Dist_graph_create_adjacent(comm, degree, candidates.data(), MPI_UNWEIGHTED, degree, candidates.data(),
                                 MPI_UNWEIGHTED, MPI_INFO_NULL, 0, &graph);
  struct GraphGuard {
    MPI_Comm& g;
    ~GraphGuard() { MPI_Comm_free(&g); }
  } guard{graph};

  // 2. To each candidate, the widened boxes of this rank's cells that reach its box.
  std::vector<double> send_boxes;
  std::vector<int> counts;
  for (const int q : candidates) {
    const std::size_t before = send_boxes.size();
    for (std::int64_t c = 0; c < n_cells; ++c) {
      const Box6 w = widened(&boxes[static_cast<std::size_t>(6 * c)], width);
      if (meet(w.data(), &all[static_cast<std::size_t>(6 * q)])) send_boxes.insert(send_boxes.end(), w.begin(), w.end());
    }
    counts.push_back(as_int(send_boxes.size() - before));
  }
  std::vector<double> their_boxes;
  std::vector<int> their_counts;
  neighbour_exchange(graph, degree, send_boxes, counts, their_boxes, their_counts);

  // 3. Per candidate, the cells of this rank that meet one of its widened boxes, sent with
  //    their faces (global ids, global orientation) and points: the candidate's ghosts.
  //    int64 message: n_cells, per cell (global id, n_faces, per face (global face, flags:
  //    1 this cell is the global owner, 2 a boundary face of the whole mesh; n_points,
  //    global point ids)), n_points, their global ids; double message: their coordinates.
  std::vector<std::int64_t> send_ints;
  std::vector<double> send_coords;
  std::vector<int> int_counts, coord_counts;
  std::vector<std::vector<std::int64_t>> cell_faces(static_cast<std::size_t>(n_cells));
  for (std::size_t f = 0; f < b.owner.size(); ++f) {
    cell_faces[static_cast<std::size_t>(b.owner[f])].push_back(static_cast<std::int64_t>(f));
    if (f < b.neighbour.size()) cell_faces[static_cast<std::size_t>(b.neighbour[f])].push_back(static_cast<std::int64_t>(f));
  }
  GhostedPolyMesh g;
  std::vector<std::vector<std::int64_t>> sent_cells(candidates.size());
  std::size_t at = 0;
  for (std::size_t k = 0; k < candidates.size(); ++k) {
    const double* first = their_boxes.data() + at;
    const std::size_t n_boxes = static_cast<std::size_t>(their_counts[k]) / 6;
    at += static_cast<std::size_t>(their_counts[k]);
    Box6 hull{inf, inf, inf, -inf, -inf, -inf};
    for (std::size_t i = 0; i < n_boxes; ++i)
      for (int d = 0; d < 3; ++d) {
        hull[d] = std::min(hull[d], first[6 * i + d]);
        hull[3 + d] = std::max(hull[3 + d], first[6 * i + 3 + d]);
      }
    // Brute force against the boxes, after the hull: the cells tested are those near the
    // candidate (docs/scaling.md gives the cost).
    for (std::int64_t c = 0; c < n_cells; ++c) {
      const double* cb = &boxes[static_cast<std::size_t>(6 * c)];
      if (!meet(cb, hull.data())) continue;
      for (std::size_t i = 0; i < n_boxes; ++i)
        if (meet(cb, first + 6 * i)) {
          sent_cells[k].push_back(c);
          break;
        }
    }
    const std::size_t ints_before = send_ints.size(), coords_before = send_coords.size();
    std::unordered_map<std::int64_t, std::int64_t> points_sent;  // local point -> order sent
    std::vector<std::int64_t> point_order;
    send_ints.push_back(static_cast<std::int64_t>(sent_cells[k].size()));
    for (const std::int64_t c : sent_cells[k]) {
      send_ints.push_back(m.cell_ids[static_cast<std::size_t>(c)]);
      send_ints.push_back(static_cast<std::int64_t>(cell_faces[static_cast<std::size_t>(c)].size()));
      for (const std::int64_t f : cell_faces[static_cast<std::size_t>(c)]) {
        const std::int64_t id = m.face_ids[static_cast<std::size_t>(f)];
        const bool reversed = id < 0;
        const bool local_owner = b.owner[static_cast<std::size_t>(f)] == c;
        const bool boundary = f >= static_cast<std::int64_t>(b.neighbour.size()) && !m.coupled[static_cast<std::size_t>(f)];
        send_ints.push_back(std::abs(id) - 1);
        send_ints.push_back((local_owner != reversed ? 1 : 0) | (boundary ? 2 : 0));
        send_ints.push_back(b.face_offsets[static_cast<std::size_t>(f) + 1] - b.face_offsets[static_cast<std::size_t>(f)]);
        const std::size_t face_at = send_ints.size();
        for (std::int64_t i = b.face_offsets[static_cast<std::size_t>(f)]; i < b.face_offsets[static_cast<std::size_t>(f) + 1]; ++i) {
          const std::int64_t p = b.face_points[static_cast<std::size_t>(i)];
          if (points_sent.emplace(p, static_cast<std::int64_t>(point_order.size())).second) point_order.push_back(p);
          send_ints.push_back(m.point_ids[static_cast<std::size_t>(p)]);
        }
        if (reversed) reverse_face(send_ints.begin() + static_cast<std::ptrdiff_t>(face_at), send_ints.end());
      }
    }
    send_ints.push_back(static_cast<std::int64_t>(point_order.size()));
    for (const std::int64_t p : point_order) {
      send_ints.push_back(m.point_ids[static_cast<std::size_t>(p)]);
      send_coords.insert(send_coords.end(), &b.points[static_cast<std::size_t>(3 * p)], &b.points[static_cast<std::size_t>(3 * p + 3)]);
    }
    int_counts.push_back(as_int(send_ints.size() - ints_before));
    coord_counts.push_back(as_int(send_coords.size() - coords_before));
  }
  std::vector<std::int64_t> recv_ints;
  std::vector<double> recv_coords;
  std::vector<int> recv_int_counts, recv_coord_counts;
  neighbour_exchange(graph, degree, send_ints, int_counts, recv_ints, recv_int_counts);
  neighbour_exchange(graph, degree, send_coords, coord_counts, recv_coords, recv_coord_counts);
  g.ghost_bytes = static_cast<std::int64_t>(8 * (recv_ints.size() + recv_coords.size()));

  // 4. The local mesh: owned points and faces as they are, then each ghost's new points and
  //    faces; a face already present (shared with an owned cell or an earlier ghost) gets
  //    its other side filled in.
  PolyMeshBuffers& out = g.mesh;
  out.points = b.points;
  std::unordered_map<std::int64_t, std::int64_t> local_point;  // global -> local
  for (std::size_t p = 0; p < m.point_ids.size(); ++p) local_point.emplace(m.point_ids[p], static_cast<std::int64_t>(p));
  std::vector<FaceEntry> faces;
  std::unordered_map<std::int64_t, std::size_t> face_at;  // global face -> entry
  for (std::size_t f = 0; f < b.owner.size(); ++f) {
    FaceEntry e;
    e.points.assign(b.face_points.begin() + b.face_offsets[f], b.face_points.begin() + b.face_offsets[f + 1]);
    const bool reversed = m.face_ids[f] < 0;
    if (reversed) reverse_face(e.points.begin(), e.points.end());
    const std::int64_t other = f < b.neighbour.size() ? b.neighbour[f] : -1;
    (reversed ? e.neighbour : e.owner) = b.owner[f];
    (reversed ? e.owner : e.neighbour) = other;
    e.global_boundary = f >= b.neighbour.size() && !m.coupled[f];
    e.global_id = std::abs(m.face_ids[f]) - 1;
    if (!face_at.emplace(e.global_id, faces.size()).second)
      fail("global face " + std::to_string(std::abs(m.face_ids[f]) - 1) + " appears twice in this rank's mesh");
    faces.push_back(std::move(e));
  }
  g.owned = n_cells;
  g.cell_ids = m.cell_ids;
  std::size_t ints = 0, coords = 0;
  for (std::size_t k = 0; k < candidates.size(); ++k) {
    HaloPeer peer;
    peer.rank = candidates[k];
    peer.owned = sent_cells[k];
    // Points first (they follow the cells in the message): find where they start.
    const std::size_t message_end = ints + static_cast<std::size_t>(recv_int_counts[k]);
    std::size_t cursor = ints;
    const std::int64_t n_ghosts = recv_ints[cursor++];
    const std::size_t cells_at = cursor;
    for (std::int64_t c = 0; c < n_ghosts; ++c) {
      cursor += 1;
      const std::int64_t n_faces = recv_ints[cursor++];
      for (std::int64_t f = 0; f < n_faces; ++f) {
        cursor += 2;
        cursor += static_cast<std::size_t>(recv_ints[cursor]) + 1;
      }
    }
    const std::int64_t n_points = recv_ints[cursor++];
    for (std::int64_t p = 0; p < n_points; ++p, ++cursor, coords += 3)
      if (local_point.emplace(recv_ints[cursor], static_cast<std::int64_t>(out.points.size() / 3)).second)
        out.points.insert(out.points.end(), &recv_coords[coords], &recv_coords[coords + 3]);
    if (cursor != message_end) throw Error(VFE_ERROR_INTERNAL, "a ghost message has the wrong length; please report this");
    cursor = cells_at;
    for (std::int64_t c = 0; c < n_ghosts; ++c) {
      const std::int64_t local = static_cast<std::int64_t>(g.cell_ids.size());
      g.cell_ids.push_back(recv_ints[cursor++]);
      g.ghost_owner.push_back(peer.rank);
      peer.ghost.push_back(local);
      const std::int64_t n_faces = recv_ints[cursor++];
      for (std::int64_t f = 0; f < n_faces; ++f) {
        const std::int64_t id = recv_ints[cursor++], flags = recv_ints[cursor++], n = recv_ints[cursor++];
        const auto [it, fresh] = face_at.emplace(id, faces.size());
        if (fresh) {
          FaceEntry e;
          for (std::int64_t i = 0; i < n; ++i) e.points.push_back(local_point.at(recv_ints[cursor + static_cast<std::size_t>(i)]));
          e.global_boundary = (flags & 2) != 0;
          e.global_id = id;
          faces.push_back(std::move(e));
        }
        cursor += static_cast<std::size_t>(n);
        FaceEntry& e = faces[it->second];
        std::int64_t& side = (flags & 1) ? e.owner : e.neighbour;
        if (side >= 0 && side != local)
          throw Error(VFE_ERROR_INTERNAL, "global face " + std::to_string(id) + " has two cells on one side; the global "
                                          "face ids do not match the mesh");
        side = local;
      }
    }
    ints = message_end;
    if (!peer.ghost.empty() || !peer.owned.empty()) g.peers.push_back(std::move(peer));
  }

  // 5. Faces in OpenFOAM's order for the arrays form: internal ones (both sides here) first,
  //    then boundary faces, each owned by its one cell here (a face whose cell here is the
  //    global neighbour is reversed). A ghost with a face that is a boundary here but not in
  //    the whole mesh is on the layer's outer edge.
  //    Within each kind, faces in the undecomposed mesh's order: a cell then lists its faces
  //    as the serial engine does, so its volume, centre and overlaps round the same way.
  std::sort(faces.begin(), faces.end(), [](const FaceEntry& a, const FaceEntry& b) { return a.global_id < b.global_id; });
  std::vector<char> on_rim(g.cell_ids.size(), 0);
  for (int pass = 0; pass < 2; ++pass)
    for (FaceEntry& e : faces) {
      const bool internal = e.owner >= 0 && e.neighbour >= 0;
      if (internal != (pass == 0)) continue;
      if (!internal && e.owner < 0) {
        reverse_face(e.points.begin(), e.points.end());
        e.owner = e.neighbour;
      }
      out.face_points.insert(out.face_points.end(), e.points.begin(), e.points.end());
      out.face_offsets.push_back(static_cast<std::int64_t>(out.face_points.size()));
      out.owner.push_back(e.owner);
      if (internal) out.neighbour.push_back(e.neighbour);
      if (!internal && !e.global_boundary) on_rim[static_cast<std::size_t>(e.owner)] = 1;
    }
  for (std::size_t c = static_cast<std::size_t>(n_cells); c < on_rim.size(); ++c)
    if (on_rim[c]) g.rim.push_back(static_cast<std::int64_t>(c));
  return g;
}

}  // namespace vfe::mpi
