// Host side of kernels/bin.cl: count, exact-size allocation, fill, sort.
#include "ops/args.hpp"

namespace penumbra::detail {

namespace {

struct BinCountArgs {
  static constexpr const char* file = "bin.cl";
  static constexpr const char* kernel = "bin_count";
  const cl::Buffer& boxes;
  cl_int n, tiles_x;
  const cl::Buffer& counts;
  auto fields() const { return std::tie(boxes, n, tiles_x, counts); }
};

struct BinFillArgs {
  static constexpr const char* file = "bin.cl";
  static constexpr const char* kernel = "bin_fill";
  const cl::Buffer& boxes;
  cl_int n, tiles_x;
  const cl::Buffer &offsets, &cursor, &items;
  auto fields() const { return std::tie(boxes, n, tiles_x, offsets, cursor, items); }
};

struct BinSortArgs {
  static constexpr const char* file = "bin.cl";
  static constexpr const char* kernel = "bin_sort";
  const cl::Buffer &offsets, &counts;
  cl_int ntiles;
  const cl::Buffer &items, &scratch;
  auto fields() const { return std::tie(offsets, counts, ntiles, items, scratch); }
};

}  // namespace

Bins bin_boxes(Kernels& k, const cl::Buffer& boxes, int n, int W, int H, int tile) {
  Context& ctx = k.ctx();
  const std::string variant = bin_define(tile);
  Bins b;
  b.tile = tile;
  b.tiles_x = (W + tile - 1) / tile;
  b.tiles_y = (H + tile - 1) / tile;
  const int ntiles = b.tiles_x * b.tiles_y;
  b.counts = upload_ints(ctx, std::vector<int>(ntiles, 0));
  auto& count = bind_args(k, BinCountArgs{boxes, n, b.tiles_x, b.counts}, variant);
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
  check_memory(ctx, 2 * total * sizeof(cl_int),  // the lists and bin_sort's scratch
               std::to_string(ntiles) + " tile lists of " + std::to_string(total) + " boxes");
  b.offsets = upload_ints(ctx, offsets);
  b.items = alloc_ints(ctx, total);
  cl::Buffer cursor = upload_ints(ctx, std::vector<int>(ntiles, 0));
  auto& fill = bind_args(k, BinFillArgs{boxes, n, b.tiles_x, b.offsets, cursor, b.items}, variant);
  launch_1d(ctx, fill, n);
  sort_lists(k, b);
  return b;
}

void sort_lists(Kernels& k, const Bins& b) {
  const int ntiles = b.tiles_x * b.tiles_y;
  const cl::Buffer scratch = alloc_ints(k.ctx(), b.total);
  auto& sort =
      bind_args(k, BinSortArgs{b.offsets, b.counts, ntiles, b.items, scratch}, bin_define(b.tile));
  const size_t group = size_t(device_defaults(k.ctx().info()).sort_group);
  if (group > 1)  // a work-group per list
    launch(k.ctx(), sort, cl::NDRange(size_t(ntiles) * group), cl::NDRange(group));
  else
    launch_1d(k.ctx(), sort, size_t(ntiles), 16);
}

}  // namespace penumbra::detail
