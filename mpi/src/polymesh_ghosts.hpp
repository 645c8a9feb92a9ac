// The ghost layer of a decomposed polyMesh: the other ranks' cells within a width of this
// rank's cells, fetched with their faces and points (global ids), merged with the owned
// cells into one local polyMesh (shared faces joined by global face id), and the halo plan
// that pairs each ghost with its owner's cell.
#pragma once

#include "halo.hpp"

#include <vfe/engine.hpp>

#include <mpi.h>

#include <cstdint>
#include <vector>

namespace vfe::mpi {

/// A rank's own cells of a decomposed polyMesh and their global ids, as decomposePar's
/// addressing files give them.
struct RankPolyMesh {
  PolyMeshBuffers mesh;                 ///< the processor mesh, in its order
  std::vector<std::int64_t> point_ids;  ///< global point of each local point
  std::vector<std::int64_t> face_ids;   ///< per local face: global face + 1, negated when the face is reversed
  std::vector<std::int64_t> cell_ids;   ///< global cell of each local cell
  std::vector<char> coupled;            ///< per local face: 1 on a processor patch (shared with another rank)
  std::int64_t cell_count() const;
};

/// Checks the ids' counts and ranges against the mesh; throws Error naming the bad entry.
void check_rank_mesh(const RankPolyMesh& m);

/// Per cell its axis-aligned bounding box: lo x, y, z, hi x, y, z.
std::vector<double> cell_boxes(const RankPolyMesh& m);

/// A rank's local mesh: its owned cells first (in their order), then the ghost cells.
struct GhostedPolyMesh {
  PolyMeshBuffers mesh;
  std::int64_t owned = 0;
  std::vector<std::int64_t> cell_ids;  ///< global cell of each local cell
  std::vector<int> ghost_owner;        ///< per ghost cell (local cell owned + i): its owner's rank
  std::vector<std::int64_t> rim;       ///< ghost cells with a face on the layer's outer edge (local indices)
  std::vector<HaloPeer> peers;         ///< the reverse-sum plan (owned indices = local ones)
  std::int64_t ghost_bytes = 0;        ///< bytes of ghost geometry this rank received
};

/// Collective. The ghosts of this rank are the other ranks' cells whose bounding box meets
/// the bounding box of one of its cells widened by `width` on every side; `boxes` are
/// cell_boxes(m). Only ranks whose bounding boxes come that close exchange anything.
GhostedPolyMesh build_ghosted(MPI_Comm comm, const RankPolyMesh& m, const std::vector<double>& boxes, double width);

}  // namespace vfe::mpi
