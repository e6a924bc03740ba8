// Stage 2 — bin: faces into screen tiles of TILE × TILE pixels, in two passes (count, then
// fill into exactly sized lists), so a list can never overflow. Each list is then sorted by
// face index: the raster sums faces in index order whatever the tiling, which makes every
// tiling (and the brute-force path) bit-identical.
//
// Buffers: fbbox F × int4 (from face_setup); count, offsets, cursor: tiles × int;
//          faces_out, scratch Σcount × int. Tiles are row-major, tiles_x per row.
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

// The end of the ascending run of a that starts at i.
inline int run_end(__global const int* a, int i, int n) {
  while (++i < n && a[i - 1] < a[i]) {
  }
  return i;
}

// Merges the ascending runs a[lo, mid) and a[mid, hi) into b[lo, hi).
inline void merge_runs(__global const int* a, int lo, int mid, int hi, __global int* b) {
  for (int i = lo, j = mid, k = lo; k < hi; ++k)
    b[k] = j >= hi || (i < mid && a[i] < a[j]) ? a[i++] : a[j++];
}

// One tile's list into face order by a natural merge sort (scratch: as long as the list): each
// pass merges neighbouring ascending runs, halving their number. bin_fill's lists interleave a
// few long runs (the work-groups running at once), so a few linear passes sort them; lists in
// any order take O(n log n).
__kernel void bin_sort(__global const int* offsets, __global const int* count, int ntiles,
                       __global int* faces_out, __global int* scratch) {
  int t = get_global_id(0);
  if (t >= ntiles) return;
  __global int* list = faces_out + offsets[t];
  __global int *a = list, *b = scratch + offsets[t];
  const int n = count[t];
  for (int runs = 2; runs > 1;) {
    runs = 0;
    for (int lo = 0; lo < n; ++runs) {
      const int mid = run_end(a, lo, n), hi = mid < n ? run_end(a, mid, n) : n;
      merge_runs(a, lo, mid, hi, b);
      lo = hi;
    }
    __global int* merged = b;
    b = a;
    a = merged;
  }
  if (a != list)
    for (int k = 0; k < n; ++k) list[k] = a[k];
}
