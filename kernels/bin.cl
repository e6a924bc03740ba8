// Stage 2 — bin: faces into screen tiles of TILE × TILE pixels, in two passes (count, then
// fill into exactly sized lists), so a list can never overflow. Each list is then sorted by
// face index: the raster sums faces in index order whatever the tiling, which makes every
// tiling (and the brute-force path) bit-identical.
//
// Buffers: fbbox F × int4 (from face_setup); count, offsets, cursor: tiles × int;
//          faces_out Σcount × int. Tiles are row-major, tiles_x per row.
// Launch: one work-item per face (bin_count, bin_fill), one per tile (bin_sort).
#ifndef TILE
#define TILE 16  // tile edge in pixels; must match the raster's TILE
#endif

__kernel void bin_count(__global const int4* fbbox, int nf, int tiles_x,
                        __global int* count) {
  int f = get_global_id(0);
  if (f >= nf) return;
  int4 b = fbbox[f];
  if (b.x > b.z) return;
  for (int ty = b.y / TILE; ty <= b.w / TILE; ++ty)
    for (int tx = b.x / TILE; tx <= b.z / TILE; ++tx) atomic_inc(&count[ty * tiles_x + tx]);
}

__kernel void bin_fill(__global const int4* fbbox, int nf, int tiles_x,
                       __global const int* offsets, __global int* cursor,
                       __global int* faces_out) {
  int f = get_global_id(0);
  if (f >= nf) return;
  int4 b = fbbox[f];
  if (b.x > b.z) return;
  for (int ty = b.y / TILE; ty <= b.w / TILE; ++ty)
    for (int tx = b.x / TILE; tx <= b.z / TILE; ++tx) {
      int t = ty * tiles_x + tx;
      faces_out[offsets[t] + atomic_inc(&cursor[t])] = f;
    }
}

inline void sift_down(__global int* a, int root, int len) {
  for (int child; (child = 2 * root + 1) < len; root = child) {
    if (child + 1 < len && a[child] < a[child + 1]) ++child;
    if (a[root] >= a[child]) return;
    int tmp = a[root];
    a[root] = a[child];
    a[child] = tmp;
  }
}

// In-place heapsort of one tile's list: O(n log n), no extra memory.
__kernel void bin_sort(__global const int* offsets, __global const int* count, int ntiles,
                       __global int* faces_out) {
  int t = get_global_id(0);
  if (t >= ntiles) return;
  __global int* a = faces_out + offsets[t];
  int n = count[t];
  for (int start = n / 2 - 1; start >= 0; --start) sift_down(a, start, n);
  for (int end = n - 1; end > 0; --end) {
    int tmp = a[0];
    a[0] = a[end];
    a[end] = tmp;
    sift_down(a, 0, end);
  }
}
