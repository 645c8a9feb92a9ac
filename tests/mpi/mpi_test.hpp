// What the libvfe_mpi tests share: particle views, reductions over ranks, and the main of an
// MPI GoogleTest program (one rank prints; the exit status is the worst over ranks, though
// the checks are reduced over ranks first, so all ranks agree anyway).
#pragma once

#include <vfe/vfe.h>

#include <mpi.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

/// Spheres with ids, the same on every rank.
struct Scene {
  std::string name;
  std::vector<double> centres, radii;
  std::vector<int64_t> ids;
  std::size_t size() const { return radii.size(); }
  double largest_volume() const {
    const double r = *std::max_element(radii.begin(), radii.end());
    return 4.0 / 3.0 * M_PI * r * r * r;
  }
  double volume() const {
    double v = 0;
    for (double r : radii) v += 4.0 / 3.0 * M_PI * r * r * r;
    return v;
  }
};

inline vfe_particles view(const double* centres, const double* radii, const int64_t* ids, int64_t n) {
  vfe_particles p{};
  p.n = n;
  p.centres = centres;
  p.radii = radii;
  p.ids = ids;
  return p;
}

inline double max_over_ranks(double v) {
  double m = 0;
  MPI_Allreduce(&v, &m, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
  return m;
}

inline int mpi_gtest_main(int argc, char** argv, int& rank, int& size) {
  MPI_Init(&argc, &argv);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  ::testing::InitGoogleTest(&argc, argv);
  if (rank != 0) {
    auto& listeners = ::testing::UnitTest::GetInstance()->listeners();
    delete listeners.Release(listeners.default_result_printer());
  }
  const int failed = RUN_ALL_TESTS();
  int any = 0;
  MPI_Allreduce(&failed, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  MPI_Finalize();
  return any;
}
