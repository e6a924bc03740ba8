// Stage 2 — bin: faces into screen tiles of TILE × TILE pixels, in two passes (count, then
// fill into exactly sized lists), so a list can never overflow. Each list is then sorted by
// face index: the raster sums faces in index order whatever the tiling, which makes every
// tiling (and the brute-force path) bit-identical.
//
// Buffers: fbbox F × int4 (from face_setup); count, offsets, cursor: tiles × int;
//          faces_out, scratch Σcount × int. Tiles are row-major, tiles_x per row.
// Launch: one work-item per face (bin_count, bin_fill), one or a work-group per tile (bin_sort).
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

// Merges a list's ascending runs pass by pass (scratch: as long as the list), halving their
// number each pass: bin_fill's lists on a CPU interleave a few long runs (the work-groups
// running at once), so a few linear passes sort them; lists in any order take O(n log n).
inline void merge_sort_list(__global int* list, __global int* scratch, int n) {
  __global int *a = list, *b = scratch;
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

// bin_sort's work-items per list (the host's sort_group): one on CPUs; on GPUs a work-group,
// which sorts a list of up to SORT_LOCAL faces in local memory by a bitonic network (bin_fill's
// atomics leave a GPU's lists in no order, and one work-item merging a list of a thousand
// faces pass by pass waited on memory for milliseconds); a longer list falls back to its first
// work-item merging it. Either way the list ends in face order, the same list.
#ifndef SORT_GROUP
#define SORT_GROUP 1
#endif
#define SORT_LOCAL 4096

#if SORT_GROUP > 1
inline void bitonic_sort_local(__local int* keys, int m, int l) {
  for (int k = 2; k <= m; k <<= 1)
    for (int j = k >> 1; j > 0; j >>= 1) {
      for (int i = l; i < m; i += SORT_GROUP) {
        const int p = i ^ j;
        if (p > i) {
          const int a = keys[i], b = keys[p];
          if (((i & k) == 0) == (a > b)) keys[i] = b, keys[p] = a;  // ascending where i & k is 0
        }
      }
      barrier(CLK_LOCAL_MEM_FENCE);
    }
}
#endif

// One tile's list into face order. Launch: one work-item per tile (SORT_GROUP 1), else
// exactly ntiles work-groups of SORT_GROUP.
__kernel void bin_sort(__global const int* offsets, __global const int* count, int ntiles,
                       __global int* faces_out, __global int* scratch) {
#if SORT_GROUP > 1
  __local int keys[SORT_LOCAL];
  const int t = get_group_id(0), l = get_local_id(0), n = count[t];
  __global int* list = faces_out + offsets[t];
  // Every work-item reaches every barrier: a list too long for local memory sorts nothing
  // there (m = 1) and is merged by the group's first work-item afterwards.
  const int in_local = n <= SORT_LOCAL ? n : 0;
  int m = 1;
  while (m < in_local) m <<= 1;
  for (int i = l; i < m; i += SORT_GROUP) keys[i] = i < in_local ? list[i] : INT_MAX;
  barrier(CLK_LOCAL_MEM_FENCE);
  bitonic_sort_local(keys, m, l);
  for (int i = l; i < in_local; i += SORT_GROUP) list[i] = keys[i];
  if (n > SORT_LOCAL && l == 0) merge_sort_list(list, scratch + offsets[t], n);
#else
  int t = get_global_id(0);
  if (t >= ntiles) return;
  merge_sort_list(faces_out + offsets[t], scratch + offsets[t], count[t]);
#endif
}
