// The halo of a block-decomposed Cartesian grid: which ghost cells of this rank's extended
// block belong to which rank's owned cells, built once from the decomposition and run
// backwards (ghost deposits summed into owners) or forwards (owner values copied to ghosts)
// on a graph communicator of the actual neighbours.
#pragma once

#include <mpi.h>

#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace vfe::mpi {

using Index3 = std::array<std::int64_t, 3>;

/// Half-open box of cell indices [lo, hi) per axis.
struct Box {
  Index3 lo{0, 0, 0}, hi{0, 0, 0};
  bool empty() const { return hi[0] <= lo[0] || hi[1] <= lo[1] || hi[2] <= lo[2]; }
  std::int64_t count() const { return empty() ? 0 : (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]); }
  Index3 extent() const { return {hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]}; }
  bool contains(const Index3& c) const {
    return c[0] >= lo[0] && c[0] < hi[0] && c[1] >= lo[1] && c[1] < hi[1] && c[2] >= lo[2] && c[2] < hi[2];
  }
};
Box intersect(const Box& a, const Box& b);
Box shifted(const Box& b, const Index3& by);

/// The decomposition every rank knows: the global grid, each rank's owned block, which axes
/// wrap, and the ghost width per axis.
struct Decomposition {
  Index3 cells{0, 0, 0};
  std::vector<Box> blocks;  // per rank
  std::array<bool, 3> periodic{false, false, false};
  Index3 ghost{0, 0, 0};
  /// Rank r's owned block plus ghosts (global, unwrapped indices): wider by ghost[d] on a
  /// periodic axis, clipped to the grid on the others (no ghost cells beyond the grid).
  Box extended(int rank) const;
};

/// Cells sent to or received from one neighbour, as boxes whose shapes pair up with the
/// neighbour's own list (same boxes, same order, cells x fastest within a box).
struct NeighbourBoxes {
  int rank = -1;
  std::vector<Box> ghost;  // in this rank's extended-block coordinates: its ghosts owned there
  std::vector<Box> owned;  // in this rank's owned-block coordinates: cells it owns that are ghosts there
  std::int64_t ghost_cells = 0, owned_cells = 0;
};

class Halo {
 public:
  Halo() = default;
  /// Builds the plan and the graph communicator; collective over comm.
  Halo(MPI_Comm comm, const Decomposition& dec, int rank);
  ~Halo();
  Halo(Halo&& other) noexcept;
  Halo& operator=(Halo&& other) noexcept;
  Halo(const Halo&) = delete;
  Halo& operator=(const Halo&) = delete;

  /// owned += the ghosts other ranks (or this one, across a periodic wall) hold for it;
  /// extended is the local field on the extended block, k values per cell. Collective.
  void reverse_sum(std::span<const double> extended, std::span<double> owned, int components) const;
  /// extended's ghost cells = their owners' values; owned cells are not written. Collective.
  void forward_fill(std::span<const double> owned, std::span<double> extended, int components) const;

  const std::vector<NeighbourBoxes>& neighbours() const { return neighbours_; }
  std::int64_t ghost_cells_sent() const;

 private:
  void run(bool reverse, std::span<const double> from, std::span<double> to, int components) const;
  void exchange(const std::vector<double>& send, const std::vector<int>& send_counts, std::vector<double>& recv,
                const std::vector<int>& recv_counts) const;
  MPI_Comm graph_ = MPI_COMM_NULL;
  Index3 extended_extent_{0, 0, 0}, owned_extent_{0, 0, 0};
  std::vector<NeighbourBoxes> neighbours_;
};

}  // namespace vfe::mpi
