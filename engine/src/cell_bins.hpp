// Binned accumulation for fields larger than a core's cache: a pass over the particles
// writes each deposit, in sequence, to the bin of its region of cells, and the commit adds
// a region's bins into the field on one thread while that region is in the cache. Private
// fields would cost every thread a field of random adds, then a merge that reads and
// clears them all: on a field of a million cells that merge did not get faster with a
// second thread (docs/performance.md, "direct with two threads on large fields"). Bins
// cost 12 bytes per deposit, whatever the thread count.
#pragma once

#include "methods/driver.hpp"

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <vector>

namespace vfe::detail {

/// Fields of at least this many cells take bins where a pass offers them: with two
/// threads, direct's private fields were ahead up to 493039 cells and even at 585225,
/// bins ahead from 728728 (docs/performance.md, "Where bins pay").
inline constexpr std::int64_t kBinnedCells = 600000;

/// Deposits of one thread and one region, filled in order; pages of a bin are chained.
struct BinPage {
  static constexpr std::int32_t kEntries = 1024;
  std::int32_t count;
  std::int32_t next;  ///< the bin's next page, or -1
  std::int32_t cells[kEntries];
  double volumes[kEntries];
};

/// One thread's access to its bins: add() appends a deposit to its region's bin (a cell
/// below 2^31), extra() takes deposits of any cell (the dropped slot included) outside
/// the bins.
class BinWriter {
 public:
  BinWriter(BinPage* pages, std::int32_t page_count, std::atomic<std::int32_t>* used, std::int32_t* tails, int shift,
            std::vector<Deposit>* extra)
      : pages_(pages), page_count_(page_count), used_(used), tails_(tails), shift_(shift), extra_(extra) {}

  void add(std::int32_t cell, double volume) {
    std::int32_t& tail = tails_[cell >> shift_];
    BinPage* page = pages_ + tail;
    if (page->count == BinPage::kEntries) [[unlikely]] {
      const std::int32_t fresh = used_->fetch_add(1, std::memory_order_relaxed);
      if (fresh >= page_count_) {  // more deposits than the pool was sized for: kept aside
        extra(cell, volume);
        return;
      }
      page->next = fresh;
      tail = fresh;
      page = pages_ + fresh;
      page->count = 0;
      page->next = -1;
    }
    page->cells[page->count] = cell;
    page->volumes[page->count++] = volume;
  }
  void extra(std::int64_t cell, double volume) { extra_->push_back({cell, volume}); }

 private:
  BinPage* pages_;
  std::int32_t page_count_;
  std::atomic<std::int32_t>* used_;
  std::int32_t* tails_;  // per region: the index of the bin's last page
  int shift_;
  std::vector<Deposit>* extra_;
};

/// The bins of one compute: a bin per (thread slot, region of 2^shift cells), pages from
/// one pool sized by the particle count, so a steady state allocates nothing.
class CellBins {
 public:
  /// Empties the bins for a compute of at most `deposits` add() calls on `cells` cells by
  /// `slots` threads. Regions of 2^18 cells, smaller where that leaves fewer than two per
  /// thread (down to 2^12).
  void start(std::int64_t cells, std::int64_t deposits, int slots) {
    cells_ = cells;
    slots_ = std::max(slots, 1);
    shift_ = 18;
    while (shift_ > 12 && regions_for(shift_) < 2 * std::int64_t(slots_)) --shift_;
    regions_ = static_cast<std::int32_t>(regions_for(shift_));
    const std::int64_t firsts = std::int64_t(slots_) * regions_;
    const std::int64_t pages = firsts + (deposits + BinPage::kEntries - 1) / BinPage::kEntries;
    if (static_cast<std::int64_t>(pages_.size()) < pages) pages_.resize(static_cast<std::size_t>(pages));
    tails_.resize(static_cast<std::size_t>(firsts));
    for (std::int32_t i = 0; i < firsts; ++i) {  // bin i starts with page i
      tails_[i] = i;
      pages_[i].count = 0;
      pages_[i].next = -1;
    }
    used_.store(static_cast<std::int32_t>(firsts), std::memory_order_relaxed);
    extra_.resize(static_cast<std::size_t>(slots_));
    for (std::vector<Deposit>& e : extra_) e.clear();
  }
  /// The writer of a thread slot in [0, slots).
  BinWriter writer(int slot) {
    return BinWriter(pages_.data(), static_cast<std::int32_t>(pages_.size()), &used_,
                     tails_.data() + std::int64_t(slot) * regions_, shift_, &extra_[static_cast<std::size_t>(slot)]);
  }
  std::int32_t regions() const { return regions_; }
  /// Region r's cells [begin, end).
  std::int64_t region_begin(std::int32_t r) const { return std::int64_t(r) << shift_; }
  std::int64_t region_end(std::int32_t r) const { return std::min(cells_, (std::int64_t(r) + 1) << shift_); }
  /// Adds region r's binned deposits into field (indexed by cell), slot by slot, each in
  /// the order written.
  void add_region(std::int32_t r, double* field) const {
    for (int s = 0; s < slots_; ++s)
      for (std::int32_t p = std::int32_t(s) * regions_ + r; p >= 0; p = pages_[p].next) {
        const BinPage& page = pages_[p];
        for (std::int32_t i = 0; i < page.count; ++i) field[page.cells[i]] += page.volumes[i];
      }
  }
  /// The deposits kept aside, per slot.
  const std::vector<std::vector<Deposit>>& extra() const { return extra_; }

 private:
  std::int64_t regions_for(int shift) const { return (cells_ + (std::int64_t(1) << shift) - 1) >> shift; }

  std::int64_t cells_ = 0;
  int slots_ = 1, shift_ = 18;
  std::int32_t regions_ = 0;
  std::vector<BinPage> pages_;
  std::atomic<std::int32_t> used_{0};
  std::vector<std::int32_t> tails_;  // per slot, per region (bin i's first page is page i)
  std::vector<std::vector<Deposit>> extra_;
};

}  // namespace vfe::detail
