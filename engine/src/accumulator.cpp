#include "accumulator.hpp"

#include <tbb/parallel_reduce.h>
#include <tbb/parallel_sort.h>

namespace vfe::detail {

Accumulator::PrivateField& Accumulator::private_field() {
  PrivateField& f = private_.local();
  if (f.field.size() != static_cast<std::size_t>(cells_ + 1)) f.field.assign(static_cast<std::size_t>(cells_ + 1), 0.0);
  return f;
}

std::int64_t Accumulator::outside_particles() const {
  std::int64_t count = 0;
  if (kept_)
    for (const DepositBlock& b : blocks_)
      for (const std::uint8_t f : b.outside) count += f;
  return count;
}

void Accumulator::abandon() {
  // Partial deposits may sit anywhere in the private fields: zero them all (a failed
  // compute may cost a pass over the fields; a later good one must not see its volume).
  if (private_dirty_) {
    for (PrivateField& f : private_) {
      std::fill(f.field.begin(), f.field.end(), 0.0);
      f.touched.clear();
    }
    private_dirty_ = false;
  }
  for (DepositBlock& b : next_) {
    b.deposits.clear();
    b.moved.clear();
  }
  pending_ = false;
}

void Accumulator::clear_solid() {
  if (touched_valid_)
    for (const std::int64_t c : touched_) solid_[static_cast<std::size_t>(c)] = 0.0;
  else
    std::fill(solid_.begin(), solid_.end(), 0.0);
  touched_.clear();
  touched_valid_ = false;
}

bool Accumulator::merge_private(tbb::task_arena& arena, bool onto_solid, CellPass* pass) {
  double dropped = 0;
  bool passed = false;
  if (plan_.touched_only) {  // only the cells the threads touched
    if (!onto_solid) {
      clear_solid();
      dropped_ = 0;
    }
    for (PrivateField& pf : private_) {
      for (const std::int64_t c : pf.touched) {
        double& x = pf.field[static_cast<std::size_t>(c)];
        if (c == cells_) {
          dropped += x;
        } else {
          double& y = solid_[static_cast<std::size_t>(c)];
          if (y == 0.0) touched_.push_back(c);
          y += x;
        }
        x = 0.0;
      }
      pf.touched.clear();
    }
    touched_valid_ = !onto_solid;
  } else {
    if (!onto_solid) {  // every cell is written below: nothing to clear
      touched_.clear();
      touched_valid_ = false;
      dropped_ = 0;
    }
    // One pass per block: the sum of the private fields written (or added) to solid_, the
    // private fields zeroed, then the caller's pass over the block.
    const std::int64_t nblocks = (cells_ + kCellBlock - 1) / kCellBlock;
    arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, nblocks), [&](const tbb::blocked_range<std::int64_t>& r) {
        double* const solid = solid_.data();
        for (std::int64_t b = r.begin(); b < r.end(); ++b) {
          const std::int64_t begin = b * kCellBlock, end = std::min(cells_, begin + kCellBlock);
          bool assign = !onto_solid;
          for (PrivateField& pf : private_) {
            if (pf.field.size() != static_cast<std::size_t>(cells_ + 1)) continue;
            double* const f = pf.field.data();
            if (assign)
              for (std::int64_t c = begin; c < end; ++c) solid[c] = f[c], f[c] = 0.0;
            else
              for (std::int64_t c = begin; c < end; ++c) solid[c] += f[c], f[c] = 0.0;
            assign = false;
          }
          if (assign) std::fill(solid + begin, solid + end, 0.0);  // no thread took part
          if (pass) pass->cells(b, begin, end, solid);
        }
      });
    });
    passed = pass != nullptr;
    for (PrivateField& pf : private_) {
      if (pf.field.size() != static_cast<std::size_t>(cells_ + 1)) continue;
      dropped += pf.field.back();
      pf.field.back() = 0.0;
    }
  }
  dropped_ += dropped;
  private_dirty_ = false;
  return passed;
}

void Accumulator::sorted_sum(tbb::task_arena& arena) {
  // Deposits of the blocks concatenated in particle order, sorted by (cell, position) and
  // summed per cell in that order: bitwise the same for any thread count.
  const std::int64_t nblocks = static_cast<std::int64_t>(next_.size());
  sort_offsets_.assign(static_cast<std::size_t>(nblocks + 1), 0);
  for (std::int64_t b = 0; b < nblocks; ++b)
    sort_offsets_[b + 1] = sort_offsets_[b] + static_cast<std::int64_t>(next_[b].deposits.size());
  const std::int64_t total = sort_offsets_[nblocks];
  sort_keys_.resize(static_cast<std::size_t>(total));
  sort_values_.resize(static_cast<std::size_t>(total));
  clear_solid();
  dropped_ = 0;
  const bool touched_only = plan_.touched_only;
  arena.execute([&] {
    tbb::parallel_for(std::int64_t(0), nblocks, [&](std::int64_t b) {
      const auto& deps = next_[b].deposits;
      for (std::size_t i = 0; i < deps.size(); ++i) {
        const std::int64_t at = sort_offsets_[b] + std::int64_t(i);
        sort_keys_[at] = {deps[i].cell, at};
        sort_values_[at] = deps[i].volume;
      }
    });
    tbb::parallel_sort(sort_keys_.begin(), sort_keys_.end());  // keys are unique
  });
  // Each task sums the runs of equal cells that start in its range, in order.
  auto run_sum = [&](std::int64_t& i) {
    const std::int64_t cell = sort_keys_[i].first;
    double sum = 0;
    for (; i < total && sort_keys_[i].first == cell; ++i) sum += sort_values_[sort_keys_[i].second];
    return std::pair(cell, sum);
  };
  if (touched_only) {  // one pass in order: the runs are the touched cells
    for (std::int64_t i = 0; i < total;) {
      const auto [cell, sum] = run_sum(i);
      if (cell == cells_) {
        dropped_ = sum;
      } else {
        solid_[static_cast<std::size_t>(cell)] = sum;
        touched_.push_back(cell);
      }
    }
    touched_valid_ = true;
    return;
  }
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, total, 8192), [&](const tbb::blocked_range<std::int64_t>& r) {
      std::int64_t i = r.begin();
      while (i > 0 && i < total && sort_keys_[i].first == sort_keys_[i - 1].first) ++i;
      while (i < r.end() && i < total) {
        const auto [cell, sum] = run_sum(i);
        if (cell == cells_)
          dropped_ = sum;
        else
          solid_[static_cast<std::size_t>(cell)] = sum;
      }
    });
  });
}

void Accumulator::convert_fixed(tbb::task_arena& arena, const std::vector<std::int64_t>* cells) {
  const int e = fixed_exponent_;
  if (cells) {
    for (const std::int64_t c : *cells) solid_[static_cast<std::size_t>(c)] = from_fixed(fixed_[static_cast<std::size_t>(c)], e);
  } else {
    arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, cells_, 8192), [&](const tbb::blocked_range<std::int64_t>& r) {
        for (std::int64_t c = r.begin(); c < r.end(); ++c)
          solid_[static_cast<std::size_t>(c)] = from_fixed(fixed_[static_cast<std::size_t>(c)], e);
      });
    });
  }
  dropped_ = from_fixed(fixed_.back(), e);
}

void Accumulator::fixed_sum(tbb::task_arena& arena) {
  // Any order gives the same integers: blocks in order, one thread (the sort this replaces
  // cost more).
  clear_solid();
  fixed_.assign(static_cast<std::size_t>(cells_ + 1), 0);
  fixed_exponent_ = plan_.unit_exponent;
  const int e = fixed_exponent_;
  if (plan_.touched_only) {
    fixed_marks_.assign(static_cast<std::size_t>(cells_ + 1), 0);
    for (const DepositBlock& b : next_)
      for (const Deposit& d : b.deposits) {
        const auto c = static_cast<std::size_t>(d.cell);
        if (!fixed_marks_[c] && d.cell != cells_) {
          fixed_marks_[c] = 1;
          touched_.push_back(d.cell);
        }
        fixed_[c] += to_fixed(d.volume, e);
      }
    convert_fixed(arena, &touched_);
    touched_valid_ = true;
  } else {
    for (const DepositBlock& b : next_)
      for (const Deposit& d : b.deposits) fixed_[static_cast<std::size_t>(d.cell)] += to_fixed(d.volume, e);
    convert_fixed(arena, nullptr);
  }
  fixed_valid_ = true;
}

void Accumulator::reduce_blocks(tbb::task_arena& arena) {
  if (plan_.fixed_point) {
    fixed_sum(arena);
    return;
  }
  if (plan_.strategy == Accumulation::sorted) {
    sorted_sum(arena);
    return;
  }
  const std::int64_t nblocks = static_cast<std::int64_t>(next_.size());
  if (plan_.strategy == Accumulation::atomic) {
    touched_.clear();
    touched_valid_ = false;
    work_.assign(static_cast<std::size_t>(cells_ + 1), 0.0);
    arena.execute([&] {
      tbb::parallel_for(std::int64_t(0), nblocks, [&](std::int64_t b) {
        for (const Deposit& d : next_[b].deposits)
          std::atomic_ref<double>(work_[static_cast<std::size_t>(d.cell)]).fetch_add(d.volume, std::memory_order_relaxed);
      });
    });
    dropped_ = work_.back();
    work_.pop_back();
    solid_.swap(work_);
    return;
  }
  private_dirty_ = true;
  arena.execute([&] {
    tbb::parallel_for(std::int64_t(0), nblocks, [&](std::int64_t b) {
      PrivateField& f = private_field();
      for (const Deposit& d : next_[b].deposits) add_private(f, d);
    });
  });
  merge_private(arena, false);
}

void Accumulator::apply_incremental(tbb::task_arena& arena) {
  // Subtract the moved particles' old deposits, add their new ones.
  const std::int64_t nblocks = static_cast<std::int64_t>(next_.size());
  if (reuse_n_ == 0) {
    clear_solid();
    dropped_ = 0;
  }
  touched_valid_ = false;
  auto apply_block = [&](std::int64_t b, auto&& add) {
    const DepositBlock& next = next_[b];
    const DepositBlock* old = b < static_cast<std::int64_t>(blocks_.size()) ? &blocks_[b] : nullptr;
    for (const std::uint32_t i : next.moved) {
      if (b * kDepositBlock + i < reuse_n_)
        for (std::uint32_t k = old->offsets[i]; k < old->offsets[i + 1]; ++k)
          add(Deposit{old->deposits[k].cell, -old->deposits[k].volume});
      for (std::uint32_t k = next.offsets[i]; k < next.offsets[i + 1]; ++k) add(next.deposits[k]);
    }
  };
  if (plan_.fixed_point) {  // exact integers: equal to a fresh sum of the same deposits
    if (reuse_n_ == 0) {
      fixed_.assign(static_cast<std::size_t>(cells_ + 1), 0);
      fixed_exponent_ = plan_.unit_exponent;
    }
    const int e = fixed_exponent_;
    // The cells the moved particles touch, repeats and all: converting a cell twice is
    // harmless, and a per-cell mark would cost a pass over the mesh per update.
    std::vector<std::int64_t> changed;
    for (std::int64_t b = 0; b < nblocks; ++b)
      apply_block(b, [&](const Deposit& d) {
        if (d.cell != cells_) changed.push_back(d.cell);
        fixed_[static_cast<std::size_t>(d.cell)] += to_fixed(d.volume, e);
      });
    convert_fixed(arena, reuse_n_ == 0 ? nullptr : &changed);
    fixed_valid_ = true;
    return;
  }
  fixed_valid_ = false;
  double dropped = 0;
  if (plan_.strategy == Accumulation::sorted) {  // block order: the same sums for any thread count
    for (std::int64_t b = 0; b < nblocks; ++b)
      apply_block(b, [&](const Deposit& d) {
        if (d.cell == cells_)
          dropped += d.volume;
        else
          solid_[static_cast<std::size_t>(d.cell)] += d.volume;
      });
  } else if (plan_.strategy == Accumulation::atomic) {
    dropped = arena.execute([&] {
      return tbb::parallel_reduce(
          tbb::blocked_range<std::int64_t>(0, nblocks), 0.0,
          [&](const tbb::blocked_range<std::int64_t>& r, double acc) {
            for (std::int64_t b = r.begin(); b < r.end(); ++b)
              apply_block(b, [&](const Deposit& d) {
                if (d.cell == cells_)
                  acc += d.volume;
                else
                  std::atomic_ref<double>(solid_[static_cast<std::size_t>(d.cell)])
                      .fetch_add(d.volume, std::memory_order_relaxed);
              });
            return acc;
          },
          std::plus<double>());
    });
  } else {
    private_dirty_ = true;
    arena.execute([&] {
      tbb::parallel_for(std::int64_t(0), nblocks, [&](std::int64_t b) {
        PrivateField& f = private_field();
        apply_block(b, [&](const Deposit& d) { add_private(f, d); });
      });
    });
    merge_private(arena, true);
  }
  dropped_ += dropped;
}

bool Accumulator::commit(tbb::task_arena& arena, CellPass* pass) {
  bool passed = false;
  committed_regions_ = 0;
  const std::int64_t nblocks = static_cast<std::int64_t>(next_.size());
  moved_list_.clear();
  if (!plan_.fixed_point) fixed_valid_ = false;
  if (plan_.incremental) {
    apply_incremental(arena);
    blocks_.resize(static_cast<std::size_t>(nblocks));
    moved_ = 0;
    for (std::int64_t b = 0; b < nblocks; ++b) {
      DepositBlock& next = next_[b];
      if (next.moved.empty()) continue;
      moved_ += static_cast<std::int64_t>(next.moved.size());
      for (const std::uint32_t i : next.moved) moved_list_.push_back(b * kDepositBlock + i);
      std::swap(next, blocks_[b]);
    }
    kept_ = reusable_ = true;
    kept_n_ = n_;
  } else if (plan_.uses_blocks()) {
    reduce_blocks(arena);
    moved_ = n_;
    if (plan_.keep_deposits) {
      blocks_.swap(next_);
      next_.resize(blocks_.size());
      kept_ = reusable_ = true;
      kept_n_ = n_;
    } else {
      kept_ = false;
    }
  } else if (plan_.strategy == Accumulation::atomic) {
    touched_.clear();
    touched_valid_ = false;
    dropped_ = work_.back();
    work_.pop_back();
    solid_.swap(work_);
    moved_ = n_;
    kept_ = false;
  } else if (plan_.binned) {
    apply_bins(arena, pass);
    committed_regions_ = bins_.regions();
    passed = pass != nullptr;
    moved_ = n_;
    kept_ = false;
  } else {
    passed = merge_private(arena, false, pass);
    moved_ = n_;
    kept_ = false;
  }
  pending_ = false;
  return passed;
}

void Accumulator::apply_bins(tbb::task_arena& arena, CellPass* pass) {
  static_assert((std::int64_t(1) << 12) % kCellBlock == 0, "a region (2^12 cells or more) holds whole blocks");
  touched_.clear();
  touched_valid_ = false;
  // The deposits kept aside are few (spheres outside the grid, a pool run dry): their
  // region picks them out of every slot's list.
  double dropped = 0;
  for (const std::vector<Deposit>& extra : bins_.extra())
    for (const Deposit& d : extra)
      if (d.cell == cells_) dropped += d.volume;
  arena.execute([&] {
    tbb::parallel_for(std::int32_t(0), bins_.regions(), [&](std::int32_t r) {
      const std::int64_t begin = bins_.region_begin(r), end = bins_.region_end(r);
      double* const solid = solid_.data();
      std::fill(solid + begin, solid + end, 0.0);
      bins_.add_region(r, solid);
      for (const std::vector<Deposit>& extra : bins_.extra())
        for (const Deposit& d : extra)
          if (d.cell >= begin && d.cell < end) solid[d.cell] += d.volume;
      if (pass)
        for (std::int64_t b = begin; b < end; b += kCellBlock)
          pass->cells(b / kCellBlock, b, std::min(end, b + kCellBlock), solid);
    });
  });
  dropped_ = dropped;
}

}  // namespace vfe::detail
