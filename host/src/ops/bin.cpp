// Host side of kernels/bin.cl: count, exact-size allocation, fill, sort.
#include "ops/ops.hpp"

namespace penumbra::detail {

Bins bin_boxes(Kernels& k, const cl::Buffer& boxes, int n, int W, int H, int tile) {
  Context& ctx = k.ctx();
  const std::string variant = bin_define(tile);
  Bins b;
  b.tile = tile;
  b.tiles_x = (W + tile - 1) / tile;
  b.tiles_y = (H + tile - 1) / tile;
  const int ntiles = b.tiles_x * b.tiles_y;
  b.counts = upload_ints(ctx, std::vector<int>(ntiles, 0));
  auto& count = k.get("bin.cl", "bin_count", variant);
  set_args(count, boxes, n, b.tiles_x, b.counts);
  launch_1d(ctx, count, n);

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
  b.items = alloc_ints(ctx, total);
  cl::Buffer cursor = upload_ints(ctx, std::vector<int>(ntiles, 0));
  auto& fill = k.get("bin.cl", "bin_fill", variant);
  set_args(fill, boxes, n, b.tiles_x, b.offsets, cursor, b.items);
  launch_1d(ctx, fill, n);
  auto& sort = k.get("bin.cl", "bin_sort", variant);
  set_args(sort, b.offsets, b.counts, ntiles, b.items);
  launch_1d(ctx, sort, ntiles, 16);
  return b;
}

}  // namespace penumbra::detail
