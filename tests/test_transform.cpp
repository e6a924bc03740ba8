// Transform stage (kernels/transform.cl) on its own: sum_rows, which sums the backward's
// per-face and per-vertex rows on the device.
//
//   SumRows.PartsAddUpToTheRowsSum  for row counts below, at and above its 1,024 parts, in
//       float and double: the parts, added in order, give the sum of the rows (the host's, in
//       double), and a second run gives the same bits.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "cl/device.hpp"
#include "ops/ops.hpp"
#include "scenes.hpp"

using namespace penumbra;
using penumbra_tests::name_of;

TEST(SumRows, PartsAddUpToTheRowsSum) {
  REQUIRE_CONTEXT(ctx);
  const size_t n = 7;
  for (Precision precision : {Precision::Float, Precision::Double}) {
    detail::Kernels kernels(*ctx, precision, Tuning{});
    for (size_t rows : {size_t(1), size_t(5), size_t(1024), size_t(1025), size_t(100003)}) {
      std::vector<double> in(rows * n), want(n, 0.0);
      for (size_t r = 0; r < rows; ++r)
        for (size_t i = 0; i < n; ++i) {
          in[r * n + i] = std::sin(0.37 * double(r) + double(i)) * double(i + 1);
          want[i] += precision == Precision::Float ? double(float(in[r * n + i])) : in[r * n + i];
        }
      const cl::Buffer buf = detail::upload_reals(*ctx, precision, in);
      std::vector<std::vector<double>> runs;
      for (int run = 0; run < 2; ++run) {
        const detail::RowParts parts = detail::sum_rows(kernels, buf, rows, n);
        EXPECT_LE(parts.parts, 1024u) << rows;
        const std::vector<double> partial =
            detail::download_reals(*ctx, precision, parts.partial, parts.parts * n);
        std::vector<double> got(n, 0.0);
        for (size_t p = 0; p < parts.parts; ++p)
          for (size_t i = 0; i < n; ++i) got[i] += partial[p * n + i];
        runs.push_back(got);
      }
      EXPECT_EQ(runs[0], runs[1]) << rows << " rows, " << name_of(precision);
      // Column i's values lie within ±(i + 1); at 100k rows float parts of 98 rows were off by
      // 5.3e-5 of that, double ones by 1.1e-13: a row left out or counted twice shows.
      const double tol = precision == Precision::Float ? 1e-3 : 1e-11;
      for (size_t i = 0; i < n; ++i)
        EXPECT_NEAR(runs[0][i], want[i], tol * double(i + 1))
            << "column " << i << ", " << rows << " rows, " << name_of(precision);
    }
  }
}
