// Host side of kernels/bin.cl: count, exact-size allocation, fill, sort.
#include <numeric>

#include "ops/ops.hpp"

namespace penumbra::detail {

void bin_faces(Kernels& k, const DeviceGeometry& g, ViewState& v) {
  Context& ctx = k.ctx();
  const int tile = k.tuning().tile;
  Bins& b = v.bins;
  b.tiles_x = (v.W + tile - 1) / tile;
  b.tiles_y = (v.H + tile - 1) / tile;
  const int ntiles = b.tiles_x * b.tiles_y;
  b.counts = upload_ints(ctx, std::vector<int>(ntiles, 0));
  auto& count = k.get("bin.cl", "bin_count");
  set_args(count, v.fbbox, g.nf, b.tiles_x, b.counts);
  launch_1d(ctx, count, g.nf);

  // The exact list sizes are known before anything is written: no list can overflow.
  auto counts = download_ints(ctx, b.counts, ntiles);
  std::vector<int> offsets(ntiles, 0);
  size_t total = 0;
  for (int t = 0; t < ntiles; ++t) {
    offsets[t] = int(total);
    total += size_t(counts[t]);
  }
  b.total = total;
  b.offsets = upload_ints(ctx, offsets);
  b.faces = alloc_ints(ctx, total);
  cl::Buffer cursor = upload_ints(ctx, std::vector<int>(ntiles, 0));
  auto& fill = k.get("bin.cl", "bin_fill");
  set_args(fill, v.fbbox, g.nf, b.tiles_x, b.offsets, cursor, b.faces);
  launch_1d(ctx, fill, g.nf);
  auto& sort = k.get("bin.cl", "bin_sort");
  set_args(sort, b.offsets, b.counts, ntiles, b.faces);
  launch_1d(ctx, sort, ntiles, 16);
}

}  // namespace penumbra::detail
