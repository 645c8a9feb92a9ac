// Distinct engines are independent (vfe.h's promise): two engines computing at the same time
// in two host threads give the fields each gives alone. Run under ThreadSanitizer in CI
// (the tsan preset), which also reports any state the engines share without synchronisation.
#include <vfe/engine.hpp>

#include "particles.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <latch>
#include <string>
#include <thread>
#include <vector>

using vfe::Engine;
using vfe::test::grid;
using vfe::test::Particles;
using vfe::test::random_spheres;
using vfe::test::run;

namespace {

struct Job {
  Engine* engine;
  const Particles* particles;
  std::string options;
};

bool bitwise_equal(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

}  // namespace

TEST(ConcurrentEngines, TwoEnginesInTwoThreadsGiveTheirSerialResults) {
  // Different meshes, methods, templates and particles, so the two share nothing but the
  // library: a Cartesian pmm engine and a graded rectilinear exact engine.
  Engine cartesian(grid(0.5, 12, 12, 12));
  const std::vector<double> graded = {0, 0.4, 0.9, 1.5, 2.2, 3.0, 3.9, 4.9, 6.0};  // cells grow along each axis
  Engine rectilinear(vfe::RectilinearGridSpec{{graded, graded, graded}});
  const Particles a = random_spheres(21, 2000, 0.5, 5.5, 0.15, 0.45);
  const Particles b = random_spheres(22, 1200, 0.5, 5.5, 0.2, 0.5);
  const std::vector<Job> jobs = {
      {&cartesian, &a, "method=pmm template=fibonacci particle_grid=60 deterministic=1"},
      {&rectilinear, &b, "method=exact deterministic=1"}};

  // Serial references: one engine after the other, each on one thread.
  std::vector<std::vector<double>> serial;
  for (const Job& j : jobs) serial.push_back(run(*j.engine, *j.particles, j.options + " threads=1"));

  // Both engines at once, each with its own two-thread arena; repeated so the computes overlap.
  constexpr int kRepeats = 4;
  std::vector<std::vector<std::vector<double>>> concurrent(jobs.size());
  std::latch start(static_cast<std::ptrdiff_t>(jobs.size()));
  std::vector<std::thread> threads;
  for (std::size_t t = 0; t < jobs.size(); ++t)
    threads.emplace_back([&, t] {
      const Job& j = jobs[t];
      start.arrive_and_wait();
      for (int r = 0; r < kRepeats; ++r) concurrent[t].push_back(run(*j.engine, *j.particles, j.options + " threads=2"));
    });
  for (std::thread& th : threads) th.join();

  for (std::size_t t = 0; t < jobs.size(); ++t) {
    // Every sphere lies inside its mesh: the field holds all of its volume.
    const double volume = jobs[t].particles->volume();
    EXPECT_NEAR(vfe::test::total(serial[t]), volume, 1e-12 * volume) << jobs[t].options;
    for (int r = 0; r < kRepeats; ++r)
      EXPECT_TRUE(bitwise_equal(concurrent[t][r], serial[t])) << jobs[t].options << ", repeat " << r;
  }
}
