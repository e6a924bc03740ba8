#!/usr/bin/env python3
"""Generate the bundled target images of the applications (plain Python 3, no third-party
modules). Run from anywhere:  python3 data/targets/make_targets.py
The files are written next to this script.

Every target is a binary image, the shape dark (0) on a light (255) background, square, seen
as penumbra's applications see it: an orthographic view of the square [-1, 1]^2 across the
view direction (image height spans 2 world units), with

  front (direction -z): image x = +x, image up = +y
  side  (direction -x): image x = -z, image up = +y
  top   (direction -y): image x = +x, image up = -z

Pixel (px, py), row 0 at the top, is the point x = (2 px + 1 - W)/W, y = (W - 2 py - 1)/W.

  silhouette_front.png, silhouette_side.png, silhouette_top.png   (128 x 128)
      The hard silhouettes of a known mesh, silhouette_shape.obj: a loft whose cross-section at
      height y is the rectangle |x| <= w(y), |z| <= d(y), where w is the half-width of a rounded
      square and d the half-width of a rounded triangle (apex up). Its front view is the rounded
      square, its side view the triangle, its top view what they imply; being the silhouettes
      of one solid, they are consistent.
  shadow_back.png, shadow_side.png   (96 x 96)
      The shadows of another known loft, shadow_shape.obj (front: a rounded triangle, side: a
      rounded diamond), cast by directional lights travelling along -z and -x onto walls
      perpendicular to them: the front and side silhouettes of the shape.
  letter_g.png, letter_e.png, letter_b.png   (128 x 128)
      Block letters G, E and B built from rectangles and rounded rectangles, drawn so that the
      three are (nearly) consistent as the front (G), side (E) and top (B) silhouettes of one
      solid, like the cover of Goedel, Escher, Bach. The script prints how much of each letter
      the visual hull of the three reproduces.
"""
import math
import os
import sys
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
sys.dont_write_bytecode = True  # no __pycache__ among the bundled data
sys.path.insert(0, os.path.dirname(HERE))
from datafiles import write_atomic, write_obj  # noqa: E402  (data/datafiles.py)


# --------------------------------------------------------------------------------------------
# PNG output (8-bit grey).

def write_png(path, rows):
    height, width = len(rows), len(rows[0])
    raw = b"".join(b"\x00" + bytes(row) for row in rows)

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    write_atomic(path, b"\x89PNG\r\n\x1a\n" +
                 chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)) +
                 chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def save_mask(name, mask):
    """mask[py][px] True on the shape -> dark pixel."""
    write_png(os.path.join(HERE, name), [[0 if v else 255 for v in row] for row in mask])


def pixel_centre(p, size):
    return (2 * p + 1 - size) / size


# --------------------------------------------------------------------------------------------
# Lofts: cross-section at height y is the rectangle |x| <= w(y), |z| <= d(y).

def rounded_square_half_width(y, half, radius):
    """Half-width at height y of the square [-half, half]^2 with corners of the given radius."""
    if abs(y) > half:
        return None
    inner = half - radius
    if abs(y) <= inner:
        return half
    dy = abs(y) - inner
    return inner + math.sqrt(max(radius * radius - dy * dy, 0.0))


def convex_offset_width(polygon, radius, y, x_max=2.0, steps=400):
    """Half-width at height y of the set of points within `radius` of the convex polygon
    (list of (x, y) vertices, counter-clockwise)."""
    def dist_to_polygon(px, py):
        inside = True
        best = float("inf")
        n = len(polygon)
        for i in range(n):
            ax, ay = polygon[i]
            bx, by = polygon[(i + 1) % n]
            ex, ey = bx - ax, by - ay
            cross = ex * (py - ay) - ey * (px - ax)
            if cross < 0:
                inside = False
            t = max(0.0, min(1.0, ((px - ax) * ex + (py - ay) * ey) / (ex * ex + ey * ey)))
            qx, qy = ax + t * ex - px, ay + t * ey - py
            best = min(best, math.hypot(qx, qy))
        return 0.0 if inside else best

    if dist_to_polygon(0.0, y) > radius:
        return None
    lo, hi = 0.0, x_max  # bisection for the right edge (the set is convex and symmetric)
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if dist_to_polygon(mid, y) <= radius:
            lo = mid
        else:
            hi = mid
    return lo


def loft(w_of_y, d_of_y, y0, y1, levels):
    """Mesh of the loft between heights y0 and y1: rings of 4 vertices, capped."""
    verts, faces = [], []
    ys = [y0 + (y1 - y0) * k / (levels - 1) for k in range(levels)]
    for y in ys:
        # A ring never collapses (a mesh without zero-area faces): at least 0.002 wide.
        w, d = max(w_of_y(y), 0.002), max(d_of_y(y), 0.002)
        # Counter-clockwise seen from +y: (+x,+z) (+x,-z) (-x,-z) (-x,+z).
        verts += [(w, y, d), (w, y, -d), (-w, y, -d), (-w, y, d)]
    for k in range(levels - 1):
        a, b = 4 * k, 4 * (k + 1)
        for i in range(4):
            j = (i + 1) % 4
            faces += [(a + i, b + i, b + j), (a + i, b + j, a + j)]
    last = 4 * (levels - 1)
    faces += [(0, 2, 1), (0, 3, 2), (last, last + 1, last + 2), (last, last + 2, last + 3)]
    return verts, faces


# Screen coordinates (image x, image up) of a world point for each named view.
VIEWS = {
    "front": lambda p: (p[0], p[1]),
    "side": lambda p: (-p[2], p[1]),
    "top": lambda p: (p[0], -p[2]),
}


def silhouette(verts, faces, view, size):
    """Hard orthographic silhouette: pixel centres inside any projected triangle."""
    proj = [VIEWS[view](v) for v in verts]
    mask = [[False] * size for _ in range(size)]
    for a, b, c in faces:
        (ax, ay), (bx, by), (cx, cy) = proj[a], proj[b], proj[c]
        area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
        if abs(area) < 1e-15:
            continue
        xmin, xmax = min(ax, bx, cx), max(ax, bx, cx)
        ymin, ymax = min(ay, by, cy), max(ay, by, cy)
        p0 = max(0, int(math.floor((xmin * size + size - 1) / 2)))
        p1 = min(size - 1, int(math.ceil((xmax * size + size - 1) / 2)))
        q0 = max(0, int(math.floor((size - 1 - ymax * size) / 2)))
        q1 = min(size - 1, int(math.ceil((size - 1 - ymin * size) / 2)))
        for py in range(q0, q1 + 1):
            y = (size - 2 * py - 1) / size
            for px in range(p0, p1 + 1):
                if mask[py][px]:
                    continue
                x = (2 * px + 1 - size) / size
                w0 = (bx - x) * (cy - y) - (by - y) * (cx - x)
                w1 = (cx - x) * (ay - y) - (cy - y) * (ax - x)
                w2 = (ax - x) * (by - y) - (ay - y) * (bx - x)
                if (w0 >= 0 and w1 >= 0 and w2 >= 0) or (w0 <= 0 and w1 <= 0 and w2 <= 0):
                    mask[py][px] = True
    return mask


# --------------------------------------------------------------------------------------------
# Letters: predicates on (u, v) in [-1, 1]^2 (u right, v up).

def in_box(u, v, u0, u1, v0, v1):
    return u0 <= u <= u1 and v0 <= v <= v1


def in_rounded_box(u, v, u0, u1, v0, v1, r_left, r_right):
    """Box with its left corners rounded by r_left and its right corners by r_right."""
    if not in_box(u, v, u0, u1, v0, v1):
        return False
    for r, cu in ((r_left, u0 + r_left), (r_right, u1 - r_right)):
        if r <= 0:
            continue
        left = cu < (u0 + u1) / 2
        if (left and u < cu) or (not left and u > cu):
            for cv in (v0 + r, v1 - r):
                top = cv > (v0 + v1) / 2
                if (top and v > cv) or (not top and v < cv):
                    if (u - cu) ** 2 + (v - cv) ** 2 > r * r:
                        return False
    return True


T = 0.40  # stroke width in letter units (the letter spans 2)


def letter_e(u, v):
    return (in_box(u, v, -1, -1 + T, -1, 1) or in_box(u, v, -1, 1, 1 - T, 1)
            or in_box(u, v, -1, 0.75, -T / 2, T / 2) or in_box(u, v, -1, 1, -1, -1 + T))


def bowl(u, v, u0, u1, v0, v1, r):
    return (in_rounded_box(u, v, u0, u1, v0, v1, 0, r)
            and not in_rounded_box(u, v, u0 + T, u1 - T, v0 + T, v1 - T, 0, max(r - T, 0.0)))


def letter_b(u, v):
    return (in_box(u, v, -1, -1 + T, -1, 1) or bowl(u, v, -1, 0.86, -T / 2, 1, 0.55)
            or bowl(u, v, -1, 1, -1, T / 2, 0.6))


def letter_g(u, v):
    ring = (in_rounded_box(u, v, -1, 1, -1, 1, 0.7, 0.7)
            and not in_rounded_box(u, v, -1 + T, 1 - T, -1 + T, 1 - T, 0.7 - T, 0.7 - T))
    gap = u > 0.2 and -0.05 < v < 1 - T - 0.02
    bar = in_box(u, v, 0.0, 1, -0.05 - T, -0.05)
    return (ring and not gap) or bar


def letter_mask(fn, size, half):
    """The letter spans [-half, half] of the view's [-1, 1]."""
    mask = []
    for py in range(size):
        row = []
        for px in range(size):
            x, y = pixel_centre(px, size), -pixel_centre(py, size)
            row.append(fn(x / half, y / half))
        mask.append(row)
    return mask


def hull_coverage(front, side, top, size):
    """Fraction of each target that the visual hull of the three reproduces (voxels aligned
    with pixels: voxel (i, j, k) at x, y, z = pixel centres of index i, j, k)."""
    # Bitsets over k (the z index). Front pixel (px = i, py = size-1-j); side pixel
    # (px = size-1-k, py = size-1-j); top pixel (px = i, py = k).
    side_row = []  # per j: bits k where side is set
    for j in range(size):
        bits = 0
        row = side[size - 1 - j]
        for k in range(size):
            if row[size - 1 - k]:
                bits |= 1 << k
        side_row.append(bits)
    top_col = []  # per i: bits k where top is set
    for i in range(size):
        bits = 0
        for k in range(size):
            if top[k][i]:
                bits |= 1 << k
        top_col.append(bits)
    front_row = []  # per j: bits i where front is set
    for j in range(size):
        bits = 0
        row = front[size - 1 - j]
        for i in range(size):
            if row[i]:
                bits |= 1 << i
        front_row.append(bits)

    def ratio(covered, total):
        return covered / total if total else 1.0

    # front (i, j): exists k with side_row[j] & top_col[i]
    cov = tot = 0
    for j in range(size):
        for i in range(size):
            if front[size - 1 - j][i]:
                tot += 1
                cov += 1 if side_row[j] & top_col[i] else 0
    r_front = ratio(cov, tot)
    # side (k, j): exists i with front_row[j] bit i and top_col[i] bit k
    cov = tot = 0
    for j in range(size):
        for k in range(size):
            if side[size - 1 - j][size - 1 - k]:
                tot += 1
                fr = front_row[j]
                ok = False
                i = 0
                while fr:
                    if fr & 1 and (top_col[i] >> k) & 1:
                        ok = True
                        break
                    fr >>= 1
                    i += 1
                cov += 1 if ok else 0
    r_side = ratio(cov, tot)
    # top (i, k): exists j with front_row[j] bit i and side_row[j] bit k
    cov = tot = 0
    for k in range(size):
        for i in range(size):
            if top[k][i]:
                tot += 1
                cov += 1 if any((front_row[j] >> i) & 1 and (side_row[j] >> k) & 1
                                for j in range(size)) else 0
    r_top = ratio(cov, tot)
    return r_front, r_side, r_top


def main():
    # Figure 6 targets: rounded square (front) and rounded triangle (side).
    half = 0.85
    tri = [(-0.72, -0.73), (0.72, -0.73), (0.0, 0.73)]  # dilated by 0.12: y in [-0.85, 0.85]
    w = lambda y: rounded_square_half_width(y, half, 0.3)
    d = lambda y: convex_offset_width(tri, 0.12, y) or 0.0
    verts, faces = loft(w, d, -half, half, 121)
    write_obj(os.path.join(HERE, "silhouette_shape.obj"), verts, faces,
              ["Loft whose front silhouette is a rounded square and side silhouette a rounded",
               "triangle (penumbra fit-silhouette targets). Generated by make_targets.py."])
    for view in ("front", "side", "top"):
        save_mask("silhouette_%s.png" % view, silhouette(verts, faces, view, 128))

    # Figure 7 targets: shadows of a loft with a rounded triangle in front, a rounded diamond
    # at the side.
    half = 0.8
    tri = [(-0.62, -0.68), (0.62, -0.68), (0.0, 0.68)]  # dilated by 0.12: y in [-0.8, 0.8]
    dia = [(0.0, -0.65), (0.5, 0.0), (0.0, 0.65), (-0.5, 0.0)]  # dilated by 0.15
    w = lambda y: convex_offset_width(tri, 0.12, y) or 0.0
    d = lambda y: convex_offset_width(dia, 0.15, y) or 0.0
    verts, faces = loft(w, d, -half, half, 121)
    write_obj(os.path.join(HERE, "shadow_shape.obj"), verts, faces,
              ["Loft whose front silhouette is a rounded triangle and side silhouette a rounded",
               "diamond (penumbra fit-shadows targets). Generated by make_targets.py."])
    save_mask("shadow_back.png", silhouette(verts, faces, "front", 96))
    save_mask("shadow_side.png", silhouette(verts, faces, "side", 96))

    # Shadow art: G (front), E (side), B (top).
    size, span = 128, 0.8
    g = letter_mask(letter_g, size, span)
    e = letter_mask(letter_e, size, span)
    b = letter_mask(letter_b, size, span)
    save_mask("letter_g.png", g)
    save_mask("letter_e.png", e)
    save_mask("letter_b.png", b)
    print("visual hull reproduces G %.4f, E %.4f, B %.4f of the letters" %
          hull_coverage(g, e, b, size))


if __name__ == "__main__":
    main()
