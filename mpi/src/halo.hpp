// The halo of a block-decomposed Cartesian grid: which ghost cells of this rank's extended
// block belong to which rank's owned cells, built once from the decomposition and run
// backwards (ghost deposits summed into owners) or forwards (owner values copied to ghosts)
// on a graph communicator of the actual neighbours.
#pragma once

#include <mpi.h>
#include <vfe/engine.hpp>

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

/// Cells exchanged with one neighbour, as cell indices in orders that pair up with the
/// neighbour's own lists: `ghost` indexes this rank's local field (owned + ghost cells) at
/// the cells owned there, in the order the neighbour lists them in its `owned`; `owned`
/// indexes this rank's owned field at the cells the neighbour holds as ghosts, in the order
/// of the neighbour's `ghost`. An index may repeat (a cell seen through two periodic images).
struct HaloPeer {
  int rank = -1;
  std::vector<std::int64_t> ghost, owned;
};

/// The plan of a block-decomposed Cartesian grid: per neighbour the boxes of ghosts owned
/// there and of owned cells that are ghosts there, enumerated in the periodic shifts' order
/// both sides share, cells x fastest within a box.
std::vector<HaloPeer> cartesian_halo(const Decomposition& dec, int rank);

class Halo {
 public:
  Halo() = default;
  /// Builds the graph communicator of the peers (which must name each other: the relation
  /// is symmetric); collective over comm.
  Halo(MPI_Comm comm, std::vector<HaloPeer> peers);
  ~Halo();
  Halo(Halo&& other) noexcept;
  Halo& operator=(Halo&& other) noexcept;
  Halo(const Halo&) = delete;
  Halo& operator=(const Halo&) = delete;

  /// owned += the ghosts other ranks (or this one, across a periodic wall) hold for it;
  /// extended is the local field (owned + ghost cells), k values per cell. Collective.
  void reverse_sum(std::span<const double> extended, std::span<double> owned, int components) const;
  /// The same in fixed point (deterministic=1): integer sums, exact in any order.
  void reverse_sum(std::span<const FixedSum> extended, std::span<FixedSum> owned, int components) const;
  /// extended's ghost cells = their owners' values; owned cells are not written. Collective.
  void forward_fill(std::span<const double> owned, std::span<double> extended, int components) const;

  const std::vector<HaloPeer>& peers() const { return peers_; }
  /// Ghost cells whose values this rank sends in one reverse sum.
  std::int64_t ghost_cells_sent() const;

 private:
  template <class T>
  void run(bool reverse, std::span<const T> from, std::span<T> to, int components) const;
  MPI_Comm graph_ = MPI_COMM_NULL;
  std::vector<HaloPeer> peers_;
};

/// One MPI_Neighbor_alltoallv of `send` (counts per neighbour of graph, in its order) into
/// recv (resized); the receive counts are exchanged first. Collective over graph.
template <class T>
void neighbour_exchange(MPI_Comm graph, int degree, const std::vector<T>& send, const std::vector<int>& send_counts,
                        std::vector<T>& recv, std::vector<int>& recv_counts);

}  // namespace vfe::mpi
