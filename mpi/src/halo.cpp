#include "halo.hpp"

#include <vfe/error.hpp>

#include <algorithm>
#include <climits>
#include <utility>

namespace vfe::mpi {

Box intersect(const Box& a, const Box& b) {
  Box r;
  for (int d = 0; d < 3; ++d) {
    r.lo[d] = std::max(a.lo[d], b.lo[d]);
    r.hi[d] = std::min(a.hi[d], b.hi[d]);
  }
  return r;
}

Box shifted(const Box& b, const Index3& by) {
  Box r = b;
  for (int d = 0; d < 3; ++d) {
    r.lo[d] += by[d];
    r.hi[d] += by[d];
  }
  return r;
}

Box Decomposition::extended(int rank) const {
  Box e = blocks[static_cast<std::size_t>(rank)];
  for (int d = 0; d < 3; ++d) {
    e.lo[d] -= ghost[d];
    e.hi[d] += ghost[d];
    if (!periodic[d]) {
      e.lo[d] = std::max<std::int64_t>(e.lo[d], 0);
      e.hi[d] = std::min(e.hi[d], cells[d]);
    }
  }
  return e;
}

namespace {

// Calls f(box, extent) for every cell of box (coordinates in an array of the given extent),
// x fastest, with the cell's index in that array: the one order both sides of a pair use.
template <class F>
void for_each_cell(const Box& box, const Index3& extent, F&& f) {
  for (std::int64_t k = box.lo[2]; k < box.hi[2]; ++k)
    for (std::int64_t j = box.lo[1]; j < box.hi[1]; ++j) {
      const std::int64_t row = extent[0] * (j + extent[1] * k);
      for (std::int64_t i = box.lo[0]; i < box.hi[0]; ++i) f(row + i);
    }
}

// Periodic images of the grid that a box reaching ghost[d] cells beyond it can touch.
std::vector<Index3> image_shifts(const Decomposition& dec) {
  std::array<std::vector<std::int64_t>, 3> per_axis;
  for (int d = 0; d < 3; ++d) {
    const std::int64_t reach = dec.periodic[d] ? dec.ghost[d] / dec.cells[d] + 1 : 0;
    for (std::int64_t m = -reach; m <= reach; ++m) per_axis[d].push_back(m * dec.cells[d]);
  }
  std::vector<Index3> shifts;
  for (std::int64_t sz : per_axis[2])
    for (std::int64_t sy : per_axis[1])
      for (std::int64_t sx : per_axis[0]) shifts.push_back({sx, sy, sz});
  return shifts;
}

int as_count(std::int64_t n) {
  if (n > INT_MAX)
    throw Error(VFE_ERROR_UNSUPPORTED, "a halo message exceeds 2^31 values; decompose over more ranks");
  return static_cast<int>(n);
}

}  // namespace

Halo::Halo(MPI_Comm comm, const Decomposition& dec, int rank) {
  const Box my_block = dec.blocks[static_cast<std::size_t>(rank)];
  const Box my_ext = dec.extended(rank);
  extended_extent_ = my_ext.extent();
  owned_extent_ = my_block.extent();
  const std::vector<Index3> shifts = image_shifts(dec);
  const Index3 zero{0, 0, 0};
  for (int q = 0; q < static_cast<int>(dec.blocks.size()); ++q) {
    NeighbourBoxes nb;
    nb.rank = q;
    const Box q_ext = dec.extended(q);
    for (const Index3& s : shifts) {
      if (q == rank && s == zero) continue;  // the owned block itself
      // Ghosts here owned by q through image s, and cells owned here that q holds as ghosts
      // through the same image: q iterates the same shifts, so the lists pair up in order.
      const Box ghost = intersect(my_ext, shifted(dec.blocks[static_cast<std::size_t>(q)], s));
      if (!ghost.empty()) {
        nb.ghost.push_back(shifted(ghost, {-my_ext.lo[0], -my_ext.lo[1], -my_ext.lo[2]}));
        nb.ghost_cells += ghost.count();
      }
      const Box theirs = intersect(q_ext, shifted(my_block, s));
      if (!theirs.empty()) {
        nb.owned.push_back(shifted(theirs, {-s[0] - my_block.lo[0], -s[1] - my_block.lo[1], -s[2] - my_block.lo[2]}));
        nb.owned_cells += theirs.count();
      }
    }
    if (!nb.ghost.empty() || !nb.owned.empty()) neighbours_.push_back(std::move(nb));
  }
  // Sources and destinations are the same ranks (the relation is symmetric), in rank order.
  std::vector<int> ranks;
  for (const NeighbourBoxes& nb : neighbours_) ranks.push_back(nb.rank);
  const int degree = static_cast<int>(ranks.size());
  MPI_Dist_graph_create_adjacent(comm, degree, ranks.data(), MPI_UNWEIGHTED, degree, ranks.data(), MPI_UNWEIGHTED,
                                 MPI_INFO_NULL, 0, &graph_);
}

Halo::~Halo() {
  if (graph_ != MPI_COMM_NULL) MPI_Comm_free(&graph_);
}

Halo::Halo(Halo&& other) noexcept { *this = std::move(other); }

Halo& Halo::operator=(Halo&& other) noexcept {
  if (this != &other) {
    if (graph_ != MPI_COMM_NULL) MPI_Comm_free(&graph_);
    graph_ = std::exchange(other.graph_, MPI_COMM_NULL);
    extended_extent_ = other.extended_extent_;
    owned_extent_ = other.owned_extent_;
    neighbours_ = std::move(other.neighbours_);
  }
  return *this;
}

std::int64_t Halo::ghost_cells_sent() const {
  std::int64_t n = 0;
  for (const NeighbourBoxes& nb : neighbours_) n += nb.ghost_cells;
  return n;
}

void Halo::exchange(const std::vector<double>& send, const std::vector<int>& send_counts, std::vector<double>& recv,
                    const std::vector<int>& recv_counts) const {
  const std::size_t n = neighbours_.size();
  std::vector<int> send_displs(n, 0), recv_displs(n, 0);
  for (std::size_t i = 1; i < n; ++i) {
    send_displs[i] = send_displs[i - 1] + send_counts[i - 1];
    recv_displs[i] = recv_displs[i - 1] + recv_counts[i - 1];
  }
  const int rc = MPI_Neighbor_alltoallv(send.data(), send_counts.data(), send_displs.data(), MPI_DOUBLE, recv.data(),
                                        recv_counts.data(), recv_displs.data(), MPI_DOUBLE, graph_);
  if (rc != MPI_SUCCESS) throw Error(VFE_ERROR_INTERNAL, "the halo exchange (MPI_Neighbor_alltoallv) failed");
}

void Halo::reverse_sum(std::span<const double> extended, std::span<double> owned, int components) const {
  run(true, extended, owned, components);
}

void Halo::forward_fill(std::span<const double> owned, std::span<double> extended, int components) const {
  run(false, owned, extended, components);
}

// One plan, two directions: reverse sends ghost boxes and adds into owned boxes, forward
// sends owned boxes and overwrites ghost boxes.
void Halo::run(bool reverse, std::span<const double> from, std::span<double> to, int components) const {
  const std::size_t k = static_cast<std::size_t>(components);
  const Index3& from_extent = reverse ? extended_extent_ : owned_extent_;
  const Index3& to_extent = reverse ? owned_extent_ : extended_extent_;
  std::vector<double> send, recv;
  std::vector<int> send_counts, recv_counts;
  std::int64_t recv_total = 0;
  for (const NeighbourBoxes& nb : neighbours_) {
    for (const Box& b : reverse ? nb.ghost : nb.owned)
      for_each_cell(b, from_extent, [&](std::int64_t c) {
        for (std::size_t j = 0; j < k; ++j) send.push_back(from[static_cast<std::size_t>(c) * k + j]);
      });
    const std::int64_t sent = reverse ? nb.ghost_cells : nb.owned_cells;
    const std::int64_t received = reverse ? nb.owned_cells : nb.ghost_cells;
    send_counts.push_back(as_count(sent * components));
    recv_counts.push_back(as_count(received * components));
    recv_total += received * components;
  }
  as_count(static_cast<std::int64_t>(send.size()));
  recv.resize(static_cast<std::size_t>(as_count(recv_total)));
  exchange(send, send_counts, recv, recv_counts);
  std::size_t at = 0;
  for (const NeighbourBoxes& nb : neighbours_)
    for (const Box& b : reverse ? nb.owned : nb.ghost)
      for_each_cell(b, to_extent, [&](std::int64_t c) {
        for (std::size_t j = 0; j < k; ++j) {
          double& cell = to[static_cast<std::size_t>(c) * k + j];
          cell = reverse ? cell + recv[at++] : recv[at++];
        }
      });
}

}  // namespace vfe::mpi
