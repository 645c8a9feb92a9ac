// Accumulation: one particle loop, and the strategies that turn its per-particle deposits
// into the solid-volume field. Strategies differ only in where a deposit goes (a thread's
// private field, an atomic add into the shared field, or the deposit blocks that sorted,
// incremental and weights keep) and how the field is then assembled; the loop, the
// failure handling and the commit are written once.
//
// Failure atomicity: the committed field (solid) changes only in commit(), after every
// particle has been computed and the caller's checks passed. Whatever a failed compute
// left in per-thread fields or blocks is cleared, so the next compute equals a fresh
// engine's.
#pragma once

#include "cell_bins.hpp"
#include "methods/driver.hpp"
#include "options.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

namespace vfe::detail {

/// Particles per deposit block: fixed, so a deterministic sum never depends on the thread
/// count; small enough that incremental redoes little for one moved particle.
inline constexpr std::int64_t kDepositBlock = 512;

/// deterministic=1: each deposit is rounded to a whole number of units 2^exponent and every
/// cell sums those integers. Integer sums are exact, so a cell's sum is the same whatever
/// the order its deposits come in (threads, particle order, ranks of a distributed mesh),
/// and incremental's subtract-and-add equals a fresh sum. 128 bits: with the unit
/// 2^-80 of the largest particle volume, a deposit is resolved to 1e-24 of it and a cell
/// holds 2^46 particle volumes before it could overflow.
inline FixedSum to_fixed(double value, int exponent) {
  return static_cast<FixedSum>(std::nearbyint(std::ldexp(value, -exponent)));
}

/// Cells per block of the passes over the field: fixed, so sums over blocks in order do
/// not depend on the thread count.
inline constexpr std::int64_t kCellBlock = 4096;

/// A pass over the committed field that commit runs where it writes every cell (private
/// fields merged, no touched_only): cells(block, begin, end, solid) for each block of
/// kCellBlock cells right after the merge wrote it, while it is in the cache; blocks run
/// on several threads at once.
class CellPass {
 public:
  virtual void cells(std::int64_t block, std::int64_t begin, std::int64_t end, const double* solid) = 0;

 protected:
  ~CellPass() = default;
};

/// How one compute accumulates: the resolved strategy and the skips that combine with it.
struct AccumulationPlan {
  Accumulation strategy = Accumulation::privatised;  ///< privatised, atomic or sorted (never automatic)
  bool touched_only = false;  ///< clear, merge and sum only touched cells (privatised or sorted)
  bool incremental = false;   ///< redo only particles that moved (keeps deposit blocks)
  bool keep_deposits = false; ///< keep every particle's deposits (weights=1)
  bool fixed_point = false;   ///< deterministic=1: sum blocks in fixed point (needs blocks)
  int unit_exponent = 0;      ///< fixed_point: the unit 2^unit_exponent (fixed_unit_exponent)
  bool binned = false;        ///< privatised by a fused pass into bins (deposit_binned), not private fields
  bool uses_blocks() const {
    return strategy == Accumulation::sorted || incremental || keep_deposits || fixed_point;
  }
};

/// Particles' deposits by blocks of kDepositBlock: particle i of block b has
/// deposits[offsets[i] .. offsets[i + 1]).
struct DepositBlock {
  std::vector<Deposit> deposits;
  std::vector<std::uint32_t> offsets;
  std::vector<std::uint32_t> moved;  ///< incremental: particles of the block redone by this compute
  std::vector<std::uint8_t> outside; ///< per particle: some of its volume met the outside policy
};

class Accumulator {
 public:
  explicit Accumulator(std::int64_t cells) : cells_(cells), solid_(static_cast<std::size_t>(cells), 0.0) {}

  std::int64_t cell_count() const { return cells_; }
  /// The committed field (solid volume per cell).
  const std::vector<double>& field() const { return solid_; }
  /// deterministic=1: the committed field in fixed point (cells values, units
  /// 2^fixed_exponent()); empty after a compute that was not deterministic.
  std::span<const FixedSum> fixed_field() const {
    return fixed_valid_ ? std::span<const FixedSum>(fixed_.data(), static_cast<std::size_t>(cells_))
                        : std::span<const FixedSum>();
  }
  int fixed_exponent() const { return fixed_exponent_; }
  /// Volume that went to the dropped slot in the committed field.
  double dropped() const { return dropped_; }
  /// The regions of cells the last commit added binned deposits in (deposit_binned), or 0.
  std::int32_t binned_regions() const { return committed_regions_; }
  /// Particles computed anew by the last commit.
  std::int64_t moved() const { return moved_; }
  /// incremental: the particles the last commit redid, in increasing order.
  const std::vector<std::int64_t>& moved_particles() const { return moved_list_; }
  /// With touched_only: the cells of the field that may be non-zero; null when any may be.
  const std::vector<std::int64_t>* touched() const { return touched_valid_ ? &touched_ : nullptr; }
  /// The kept per-particle deposits of the committed field (incremental, weights), or empty.
  std::span<const DepositBlock> blocks() const {
    return kept_ ? std::span<const DepositBlock>(blocks_) : std::span<const DepositBlock>();
  }
  std::int64_t kept_particles() const { return kept_ ? kept_n_ : 0; }
  /// With kept blocks: the particles some of whose volume met the outside policy.
  std::int64_t outside_particles() const;
  /// incremental starts afresh next time (the options changed); the kept deposits still
  /// describe the last compute (its weights).
  void invalidate_kept() { reusable_ = false; }

  /// Phase 1: computes the deposits of particles [0, n) under the plan in the arena
  /// (incremental: only particles beyond the kept ones and those moved(p) says moved).
  /// particle(s, p) fills s.deposits. Throws what particle throws, after clearing every
  /// partial result.
  template <class ParticleFn, class MovedFn>
  void deposit(tbb::task_arena& arena, tbb::enumerable_thread_specific<Scratch>& scratch, const AccumulationPlan& plan,
               std::int64_t n, ParticleFn&& particle, MovedFn&& moved);
  /// Phase 1 by the caller's own pass over the particles, adding into the threads' private
  /// fields (a fused validate-and-deposit loop): pass(thread_field) where thread_field()
  /// gives this thread's field of cells + 1 values (the last: the dropped slot). Needs a
  /// privatised plan without blocks or touched_only. Returns what pass returns; when pass
  /// throws, what it added is cleared.
  template <class Pass>
  auto deposit_private(const AccumulationPlan& plan, std::int64_t n, Pass&& pass) {
    plan_ = plan;
    n_ = n;
    pending_ = true;
    private_dirty_ = true;
    try {
      return pass([this] { return private_field().field.data(); });
    } catch (...) {
      abandon();
      throw;
    }
  }
  /// Phase 1 as deposit_private, into bins by regions of cells (cell_bins.hpp), for a plan
  /// with `binned`: pass(thread_bins) where thread_bins() gives this
  /// thread's BinWriter, add() for at most n deposits of cells below cell_count(), extra()
  /// for others (the dropped slot: cell_count()). Runs in the arena.
  template <class Pass>
  auto deposit_binned(tbb::task_arena& arena, const AccumulationPlan& plan, std::int64_t n, Pass&& pass) {
    plan_ = plan;
    n_ = n;
    pending_ = true;
    bins_.start(cells_, n, arena.max_concurrency());
    try {
      return pass([this] { return bins_.writer(tbb::this_task_arena::current_thread_index()); });
    } catch (...) {
      abandon();
      throw;
    }
  }
  /// Drops phase 1's results (a check after phase 1 failed).
  void abandon();
  /// Phase 2: makes phase 1's deposits the committed field. Returns whether it ran pass
  /// (when given) over every block of cells.
  bool commit(tbb::task_arena& arena, CellPass* pass = nullptr);

 private:
  struct PrivateField {
    std::vector<double> field;          // cells + 1 values (last: dropped), zero between computes
    std::vector<std::int64_t> touched;  // touched_only: the cells it holds volume in
  };
  PrivateField& private_field();
  void add_private(PrivateField& f, const Deposit& d) {
    double& x = f.field[static_cast<std::size_t>(d.cell)];
    if (plan_.touched_only && x == 0.0) f.touched.push_back(d.cell);
    x += d.volume;
  }
  /// Adds the private fields into solid_ (cleared first unless onto_solid) and zeroes them;
  /// runs pass over the blocks of cells unless touched_only (returns whether it did).
  bool merge_private(tbb::task_arena& arena, bool onto_solid, CellPass* pass = nullptr);
  /// Makes solid_ the sum of the bins, region by region, and runs pass over its blocks.
  void apply_bins(tbb::task_arena& arena, CellPass* pass);
  void reduce_blocks(tbb::task_arena& arena);
  void sorted_sum(tbb::task_arena& arena);
  /// Makes solid_ (and dropped_) the doubles of fixed_ at the cells listed, or every cell.
  void convert_fixed(tbb::task_arena& arena, const std::vector<std::int64_t>* cells);
  void fixed_sum(tbb::task_arena& arena);
  void apply_incremental(tbb::task_arena& arena);
  /// Clears the committed field where it may be non-zero.
  void clear_solid();

  std::int64_t cells_;
  std::vector<double> solid_;
  double dropped_ = 0;
  std::int64_t moved_ = 0;
  std::vector<std::int64_t> moved_list_;

  // Phase 1's state.
  AccumulationPlan plan_;
  std::int64_t n_ = 0;
  bool pending_ = false;
  std::vector<double> work_;  // atomic: the field being computed (+1 slot: dropped)
  tbb::enumerable_thread_specific<PrivateField> private_;
  bool private_dirty_ = false;
  CellBins bins_;  // deposit_binned's deposits (plan_.binned)
  std::int32_t committed_regions_ = 0;

  // Blocks: those of phase 1 (next_) and the committed ones (blocks_: incremental, weights).
  std::vector<DepositBlock> blocks_, next_;
  bool kept_ = false;      ///< blocks_ hold the committed field's deposits
  bool reusable_ = false;  ///< and incremental may reuse them
  std::int64_t kept_n_ = 0, reuse_n_ = 0;

  // touched_only: the cells of solid_ that may be non-zero.
  std::vector<std::int64_t> touched_;
  bool touched_valid_ = false;

  // fixed_point: the committed field as integers (cells + 1: the last is dropped), valid
  // after a fixed-point commit, in units 2^fixed_exponent_.
  std::vector<FixedSum> fixed_;
  bool fixed_valid_ = false;
  int fixed_exponent_ = 0;
  std::vector<std::uint8_t> fixed_marks_;  // touched_only: cells listed once

  // sorted: (cell, position) keys and values.
  std::vector<std::pair<std::int64_t, std::int64_t>> sort_keys_;
  std::vector<double> sort_values_;
  std::vector<std::int64_t> sort_offsets_;
};

template <class ParticleFn, class MovedFn>
void Accumulator::deposit(tbb::task_arena& arena, tbb::enumerable_thread_specific<Scratch>& scratch,
                          const AccumulationPlan& plan, std::int64_t n, ParticleFn&& particle, MovedFn&& moved) {
  plan_ = plan;
  n_ = n;
  pending_ = true;
  try {
    const std::int64_t nblocks = (n + kDepositBlock - 1) / kDepositBlock;
    if (plan.uses_blocks()) {
      // A fixed-point field continues only in the same unit (and a double one only as doubles).
      const bool same_sums = plan.fixed_point ? fixed_valid_ && fixed_exponent_ == plan.unit_exponent : !fixed_valid_;
      const bool fresh = !plan.incremental || !kept_ || !reusable_ || n < kept_n_ || !same_sums;
      reuse_n_ = fresh ? 0 : kept_n_;
      next_.resize(static_cast<std::size_t>(nblocks));
      arena.execute([&] {
        tbb::parallel_for(std::int64_t(0), nblocks, [&](std::int64_t b) {
          const std::int64_t first = b * kDepositBlock, count = std::min(n, first + kDepositBlock) - first;
          DepositBlock& next = next_[static_cast<std::size_t>(b)];
          next.moved.clear();
          for (std::int64_t i = 0; i < count; ++i)
            if (first + i >= reuse_n_ || moved(first + i)) next.moved.push_back(static_cast<std::uint32_t>(i));
          next.deposits.clear();
          next.offsets.assign(1, 0);
          next.outside.clear();
          if (next.moved.empty()) return;  // the kept block stands
          Scratch& s = scratch.local();
          const DepositBlock* old = first < reuse_n_ ? &blocks_[static_cast<std::size_t>(b)] : nullptr;
          std::size_t m = 0;
          for (std::int64_t i = 0; i < count; ++i) {
            if (m < next.moved.size() && next.moved[m] == i) {
              s.deposits.clear();
              const std::int64_t outside_before = s.outside_particles;
              particle(s, first + i);
              next.deposits.insert(next.deposits.end(), s.deposits.begin(), s.deposits.end());
              next.outside.push_back(s.outside_particles != outside_before);
              ++m;
            } else {  // kept particles lie below reuse_n_, so their old deposits exist
              next.deposits.insert(next.deposits.end(), old->deposits.begin() + old->offsets[i],
                                   old->deposits.begin() + old->offsets[i + 1]);
              next.outside.push_back(old->outside[i]);
            }
            next.offsets.push_back(static_cast<std::uint32_t>(next.deposits.size()));
          }
        });
      });
    } else if (plan.strategy == Accumulation::atomic) {
      work_.assign(static_cast<std::size_t>(cells_ + 1), 0.0);
      arena.execute([&] {
        tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, n, 256), [&](const tbb::blocked_range<std::int64_t>& r) {
          Scratch& s = scratch.local();
          for (std::int64_t p = r.begin(); p < r.end(); ++p) {
            s.deposits.clear();
            particle(s, p);
            for (const Deposit& d : s.deposits)
              std::atomic_ref<double>(work_[static_cast<std::size_t>(d.cell)]).fetch_add(d.volume, std::memory_order_relaxed);
          }
        });
      });
    } else {
      private_dirty_ = true;
      arena.execute([&] {
        tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, n, 256), [&](const tbb::blocked_range<std::int64_t>& r) {
          Scratch& s = scratch.local();
          PrivateField& f = private_field();
          for (std::int64_t p = r.begin(); p < r.end(); ++p) {
            s.deposits.clear();
            particle(s, p);
            for (const Deposit& d : s.deposits) add_private(f, d);
          }
        });
      });
    }
  } catch (...) {
    abandon();
    throw;
  }
}

}  // namespace vfe::detail
