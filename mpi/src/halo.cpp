#include "halo.hpp"

#include <vfe/error.hpp>

#include <algorithm>
#include <climits>
#include <string>
#include <type_traits>
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

std::vector<HaloPeer> cartesian_halo(const Decomposition& dec, int rank) {
  const Box my_block = dec.blocks[static_cast<std::size_t>(rank)];
  const Box my_ext = dec.extended(rank);
  const Index3 extended_extent = my_ext.extent(), owned_extent = my_block.extent();
  const std::vector<Index3> shifts = image_shifts(dec);
  const Index3 zero{0, 0, 0};
  std::vector<HaloPeer> peers;
  for (int q = 0; q < static_cast<int>(dec.blocks.size()); ++q) {
    HaloPeer peer;
    peer.rank = q;
    const Box q_ext = dec.extended(q);
    for (const Index3& s : shifts) {
      if (q == rank && s == zero) continue;  // the owned block itself
      // Ghosts here owned by q through image s, and cells owned here that q holds as ghosts
      // through the same image: q iterates the same shifts, so the lists pair up in order.
      const Box ghost = intersect(my_ext, shifted(dec.blocks[static_cast<std::size_t>(q)], s));
      if (!ghost.empty())
        for_each_cell(shifted(ghost, {-my_ext.lo[0], -my_ext.lo[1], -my_ext.lo[2]}), extended_extent,
                      [&](std::int64_t c) { peer.ghost.push_back(c); });
      const Box theirs = intersect(q_ext, shifted(my_block, s));
      if (!theirs.empty())
        for_each_cell(shifted(theirs, {-s[0] - my_block.lo[0], -s[1] - my_block.lo[1], -s[2] - my_block.lo[2]}),
                      owned_extent, [&](std::int64_t c) { peer.owned.push_back(c); });
    }
    if (!peer.ghost.empty() || !peer.owned.empty()) peers.push_back(std::move(peer));
  }
  return peers;
}

Halo::Halo(MPI_Comm comm, std::vector<HaloPeer> peers) : peers_(std::move(peers)) {
  // Sources and destinations are the same ranks (the relation is symmetric).
  std::vector<int> ranks;
  for (const HaloPeer& p : peers_) ranks.push_back(p.rank);
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
    peers_ = std::move(other.peers_);
  }
  return *this;
}

std::int64_t Halo::ghost_cells_sent() const {
  std::int64_t n = 0;
  for (const HaloPeer& p : peers_) n += static_cast<std::int64_t>(p.ghost.size());
  return n;
}

template <class T>
MPI_Datatype mpi_type() {
  if constexpr (std::is_same_v<T, double>) {
    return MPI_DOUBLE;
  } else if constexpr (std::is_same_v<T, std::int64_t>) {
    return MPI_INT64_T;
  } else {
    static_assert(std::is_same_v<T, FixedSum>);
    static const MPI_Datatype fixed = [] {  // 128-bit integers as two 64-bit words, moved as they are
      MPI_Datatype t;
      MPI_Type_contiguous(2, MPI_INT64_T, &t);
      MPI_Type_commit(&t);
      return t;
    }();
    return fixed;
  }
}

template <class T>
void neighbour_exchange(MPI_Comm graph, int degree, const std::vector<T>& send, const std::vector<int>& send_counts,
                        std::vector<T>& recv, std::vector<int>& recv_counts) {
  const MPI_Datatype type = mpi_type<T>();
  const std::size_t n = static_cast<std::size_t>(degree);
  recv_counts.assign(n, 0);
  if (MPI_Neighbor_alltoall(send_counts.data(), 1, MPI_INT, recv_counts.data(), 1, MPI_INT, graph) != MPI_SUCCESS)
    throw Error(VFE_ERROR_INTERNAL, "the halo's count exchange (MPI_Neighbor_alltoall) failed");
  std::vector<int> send_displs(n, 0), recv_displs(n, 0);
  std::int64_t total = n ? recv_counts[0] : 0;
  for (std::size_t i = 1; i < n; ++i) {
    send_displs[i] = as_count(std::int64_t(send_displs[i - 1]) + send_counts[i - 1]);
    recv_displs[i] = as_count(std::int64_t(recv_displs[i - 1]) + recv_counts[i - 1]);
    total += recv_counts[i];
  }
  recv.resize(static_cast<std::size_t>(total));
  if (MPI_Neighbor_alltoallv(send.data(), send_counts.data(), send_displs.data(), type, recv.data(), recv_counts.data(),
                             recv_displs.data(), type, graph) != MPI_SUCCESS)
    throw Error(VFE_ERROR_INTERNAL, "the halo exchange (MPI_Neighbor_alltoallv) failed");
}
template void neighbour_exchange<double>(MPI_Comm, int, const std::vector<double>&, const std::vector<int>&,
                                         std::vector<double>&, std::vector<int>&);
template void neighbour_exchange<std::int64_t>(MPI_Comm, int, const std::vector<std::int64_t>&,
                                               const std::vector<int>&, std::vector<std::int64_t>&, std::vector<int>&);
template void neighbour_exchange<FixedSum>(MPI_Comm, int, const std::vector<FixedSum>&, const std::vector<int>&,
                                           std::vector<FixedSum>&, std::vector<int>&);

void Halo::reverse_sum(std::span<const double> extended, std::span<double> owned, int components) const {
  run(true, extended, owned, components);
}

void Halo::reverse_sum(std::span<const FixedSum> extended, std::span<FixedSum> owned, int components) const {
  run(true, extended, owned, components);
}

void Halo::forward_fill(std::span<const double> owned, std::span<double> extended, int components) const {
  run(false, owned, extended, components);
}

// One plan, two directions: reverse sends ghost cells and adds into owned cells, forward
// sends owned cells and overwrites ghost cells.
template <class T>
void Halo::run(bool reverse, std::span<const T> from, std::span<T> to, int components) const {
  const std::size_t k = static_cast<std::size_t>(components);
  std::vector<T> send, recv;
  std::vector<int> send_counts, recv_counts;
  for (const HaloPeer& p : peers_) {
    const std::vector<std::int64_t>& out = reverse ? p.ghost : p.owned;
    for (const std::int64_t c : out)
      for (std::size_t j = 0; j < k; ++j) send.push_back(from[static_cast<std::size_t>(c) * k + j]);
    send_counts.push_back(as_count(static_cast<std::int64_t>(out.size()) * components));
  }
  neighbour_exchange(graph_, static_cast<int>(peers_.size()), send, send_counts, recv, recv_counts);
  std::size_t at = 0;
  for (const HaloPeer& p : peers_) {
    const std::vector<std::int64_t>& in = reverse ? p.owned : p.ghost;
    if (recv_counts[static_cast<std::size_t>(&p - peers_.data())] != static_cast<std::int64_t>(in.size() * k))
      throw Error(VFE_ERROR_INTERNAL, "a halo message from rank " + std::to_string(p.rank) +
                                          " does not match this rank's plan; please report this");
    for (const std::int64_t c : in)
      for (std::size_t j = 0; j < k; ++j) {
        T& cell = to[static_cast<std::size_t>(c) * k + j];
        cell = reverse ? cell + recv[at++] : recv[at++];
      }
  }
}

}  // namespace vfe::mpi
