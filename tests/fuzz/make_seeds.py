#!/usr/bin/env python3
"""Writes the seed corpora of the fuzzers: tests/fuzz/{obj,scene,image,npy}/.

A few valid files of each kind (the shapes the loaders are meant to read) and a few invalid
ones (each a different reason to refuse). Standard library only. The two JPEG seeds were
written by stb_image_write (stbi_write_jpg, 4x4 RGB at quality 90 and 2x2 grey at 50) and
are kept here as base64. Inputs the fuzzers found to break a loader are kept, minimised, as
regression-* (at the end of this file), so that every fuzzing run replays them; each also has a
test in tests/test_errors.cpp.
"""
import base64
import os
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))


def put(folder, name, data):
    os.makedirs(os.path.join(HERE, folder), exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(HERE, folder, name), "wb") as f:
        f.write(data)


# ---- OBJ ----------------------------------------------------------------------------------
TETRA = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
put("obj", "tetra.obj", TETRA)
put("obj", "quad_colors.obj", "# a quad with vertex colours\nv -1 0 -1 1 0 0\nv 1 0 -1 0 1 0\n"
    "v 1 0 1 0 0 1\nv -1 0 1 1 1 1\nf 1 2 3 4\n")
put("obj", "normals_uvs.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\n"
    "o thing\ng part\ns off\nf 1/1/1 2/2/1 3/3/1\nf 1//1 3//1 2//1\n")
put("obj", "relative.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 1 1 0\nf -3 -1 -2\n")
put("obj", "pentagon.obj", "v 1 0 0\nv 0.31 0.95 0\nv -0.81 0.59 0\nv -0.81 -0.59 0\n"
    "v 0.31 -0.95 0\nf 1 2 3 4 5\n")
put("obj", "crlf_w.obj", "v 0 0 0 1\r\nv 2 0 0 1\r\nv 0 2 0 1\r\nf 1 2 3\r\n")
put("obj", "bad_index_zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n")
put("obj", "bad_index_range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")
put("obj", "bad_number.obj", "v 0 0 zero\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
put("obj", "bad_nonfinite.obj", "v 0 0 inf\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
put("obj", "bad_degenerate.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")
put("obj", "bad_no_faces.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n")
put("obj", "bad_repeat.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 1 2\n")
put("obj", "bad_corner.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/2/3/4 2 3\n")

# ---- scene JSON ---------------------------------------------------------------------------
put("scene", "minimal.json", '{"meshes": [{"file": "tetra.obj"}], "cameras": [{}]}\n')
put("scene", "full.json", """{
  "meshes": [
    {"file": "tetra.obj", "name": "occluder", "translate": [0, 1, 0], "scale": 0.5,
     "albedo": [0.9, 0.2, 0.2]},
    {"file": "tetra.obj", "name": "ground", "scale": [4, -0.1, 4]}
  ],
  "cameras": [
    {"eye": [0, 3, 6], "target": [0, 0.5, 0], "up": [0, 1, 0], "projection": "perspective",
     "fov": 40, "near": 0.1, "far": 20, "width": 32, "height": 24},
    {"eye": [5, 5, 0], "target": [0, 0, 0], "projection": "orthographic", "half_height": 2,
     "width": 16, "height": 16}
  ],
  "lights": [
    {"type": "point", "position": [-2, 5, 3], "color": [1, 0.9, 0.8], "intensity": 0.8,
     "size": 0.3},
    {"type": "directional", "direction": [0.3, -1, 0.2], "color": [0.2, 0.2, 0.3],
     "frustum": {"target": [0, 0, 0], "up": [0, 0, 1], "half_size": 3, "distance": 8,
                 "near": 1, "far": 16}}
  ],
  "ambient": 0.2,
  "background": [1, 1, 1],
  "render": {"sigma": 1e-4, "gamma": 1e-3, "eps": 1e-3, "dist_eps": 1e-4, "sigma_s": 2,
             "lambda_eps": 1e-3, "gamma_s": 0.02, "beta": 0.05, "gamma_p": 10,
             "cull_backfaces": false, "shadows": "soft", "sampling": "exact",
             "shadow_map_size": 64, "light_sigma": 0, "light_gamma": 0, "weight_eps": 1e-10}
}
""")
put("scene", "point_frustum.json", '{"meshes": [{"file": "tetra.obj"}], "cameras": [{"eye": '
    '[0, 0, 4]}], "lights": [{"position": [0, 4, 0], "frustum": {"target": [0, 0, 0], '
    '"up": [0, 0, 1], "fov": 50, "near": 0.5, "far": 10}}], "render": {"shadows": "hard"}}\n')
put("scene", "bad_syntax.json", '{"meshes": [{"file": "tetra.obj"}], "cameras": [{]}\n')
put("scene", "bad_key.json", '{"meshes": [{"file": "tetra.obj"}], "cameras": [{"eyes": [0,0,1]}]}\n')
put("scene", "bad_type.json", '{"meshes": [{"file": "tetra.obj"}], "cameras": [{"width": 2.5}]}\n')
put("scene", "bad_mesh.json", '{"meshes": [{"file": "bad.obj"}], "cameras": [{}]}\n')
put("scene", "bad_missing.json", '{"meshes": [{"file": "missing.obj"}], "cameras": [{}]}\n')
put("scene", "bad_params.json", '{"meshes": [{"file": "tetra.obj"}], "cameras": [{}], '
    '"render": {"sigma": 2, "shadow_map_size": 0}}\n')
put("scene", "bad_camera.json", '{"meshes": [{"file": "tetra.obj"}], "cameras": [{"eye": [0, 0, 0], '
    '"target": [0, 0, 0], "near": 5, "far": 1}]}\n')


# ---- images -------------------------------------------------------------------------------
def png(width, height, bit_depth, color_type, rows, palette=None, trns=None, empty_idat=False):
    def chunk(kind, body):
        return (struct.pack(">I", len(body)) + kind + body +
                struct.pack(">I", zlib.crc32(kind + body) & 0xffffffff))
    raw = b"".join(b"\x00" + r for r in rows)
    out = b"\x89PNG\r\n\x1a\n"
    out += chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, bit_depth, color_type, 0, 0, 0))
    if palette:
        out += chunk(b"PLTE", palette)
    if trns:
        out += chunk(b"tRNS", trns)
    if empty_idat:
        out += chunk(b"IDAT", b"")
    out += chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")
    return out


put("image", "grey_1x1.png", png(1, 1, 8, 0, [b"\x80"]))
put("image", "rgb_2x2.png", png(2, 2, 8, 2, [b"\xff\x00\x00\x00\xff\x00", b"\x00\x00\xff\xff\xff\xff"]))
put("image", "rgba_2x1.png", png(2, 1, 8, 6, [b"\x10\x20\x30\x40\x50\x60\x70\x80"]))
put("image", "grey16_2x2.png", png(2, 2, 16, 0, [b"\x00\x00\xff\xff", b"\x80\x00\x12\x34"]))
put("image", "palette_3x1.png", png(3, 1, 8, 3, [b"\x00\x01\x02"],
                                    palette=b"\xff\x00\x00\x00\xff\x00\x00\x00\xff",
                                    trns=b"\xff\x80"))
put("image", "bits1_8x2.png", png(8, 2, 1, 0, [b"\xa5", b"\x5a"]))
put("image", "grey_alpha_1x2.png", png(1, 2, 8, 4, [b"\x40\xff", b"\xc0\x00"]))
put("image", "bad_truncated.png", png(4, 4, 8, 2, [b"\x00" * 12] * 4)[:40])
put("image", "bad_crc.png", png(1, 1, 8, 0, [b"\x80"])[:-1] + b"\x00")
put("image", "bad_magic.bin", b"not an image at all\n")
# BMP: 2x2, 24 bits per pixel, rows padded to 4 bytes, bottom-up.
bmp_pixels = b"\x00\x00\xff\x00\xff\x00\x00\x00" + b"\xff\x00\x00\xff\xff\xff\x00\x00"
put("image", "rgb_2x2.bmp", b"BM" + struct.pack("<IHHI", 54 + len(bmp_pixels), 0, 0, 54) +
    struct.pack("<IiiHHIIiiII", 40, 2, 2, 1, 24, 0, len(bmp_pixels), 2835, 2835, 0, 0) + bmp_pixels)
put("image", "grey_3x2.pgm", b"P5\n3 2\n255\n" + bytes([0, 60, 120, 180, 240, 255]))
put("image", "rgb_1x2.ppm", b"P6\n# comment\n1 2\n255\n" + bytes([255, 0, 0, 0, 0, 255]))
put("image", "flat_2x1.hdr", b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 2\n" +
    bytes([128, 64, 32, 129, 10, 20, 30, 128]))
put("image", "grey_2x2.tga", bytes([0, 0, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2, 0, 2, 0, 8, 0]) +
    bytes([0, 80, 160, 255]))
put("image", "rgb_1x1.gif", b"GIF89a\x01\x00\x01\x00\x80\x00\x00\xff\x00\x00\x00\x00\x00"
    b",\x00\x00\x00\x00\x01\x00\x01\x00\x00\x02\x02D\x01\x00;")
RGB_4X4_JPG = "/9j/4AAQSkZJRgABAQAAAQABAAD/2wCEAAMCAgMCAgMDAwMEAwMEBQgFBQQEBQoHBwYIDAoMDAsKCwsNDhIQDQ4RDgsLEBYQERMUFRUVDA8XGBYUGBIUFRQBAwQEBQQFCQUFCRQNCw0UFBQUFBQUFBQUFBQUFBQUFBQUFBQUFBQUFBQUFBQUFBQUFBQUFBQUFBQUFBQUFBQUFP/AABEIAAQABAMBIgACEQEDEQH/xAGiAAABBQEBAQEBAQAAAAAAAAAAAQIDBAUGBwgJCgsQAAIBAwMCBAMFBQQEAAABfQECAwAEEQUSITFBBhNRYQcicRQygZGhCCNCscEVUtHwJDNicoIJChYXGBkaJSYnKCkqNDU2Nzg5OkNERUZHSElKU1RVVldYWVpjZGVmZ2hpanN0dXZ3eHl6g4SFhoeIiYqSk5SVlpeYmZqio6Slpqeoqaqys7S1tre4ubrCw8TFxsfIycrS09TV1tfY2drh4uPk5ebn6Onq8fLz9PX29/j5+gEAAwEBAQEBAQEBAQAAAAAAAAECAwQFBgcICQoLEQACAQIEBAMEBwUEBAABAncAAQIDEQQFITEGEkFRB2FxEyIygQgUQpGhscEJIzNS8BVictEKFiQ04SXxFxgZGiYnKCkqNTY3ODk6Q0RFRkdISUpTVFVWV1hZWmNkZWZnaGlqc3R1dnd4eXqCg4SFhoeIiYqSk5SVlpeYmZqio6Slpqeoqaqys7S1tre4ubrCw8TFxsfIycrS09TV1tfY2dri4+Tl5ufo6ery8/T19vf4+fr/2gAMAwEAAhEDEQA/APePBH7Enwm/4R63/wCKf/8AHl9v9mt7/hiT4Tf9C/8A+PL/APE1614I/wCRet/8+lb1dJzn/9k="
put("image", "rgb_4x4.jpg", base64.b64decode(RGB_4X4_JPG))
put("image", "grey_2x2.jpg", base64.b64decode("/9j/4AAQSkZJRgABAQAAAQABAAD/2wCEABALDA4MChAODQ4SERATGCgaGBYWGDEjJR0oOjM9PDkzODdASFxOQERXRTc4UG1RV19iZ2hnPk1xeXBkeFxlZ2MBERISGBUYLxoaL2NCOEJjY2NjY2NjY2NjY2NjY2NjY2NjY2NjY2NjY2NjY2NjY2NjY2NjY2NjY2NjY2NjY2NjY//AABEIAAIAAgMBIgACEQEDEQH/xAGiAAABBQEBAQEBAQAAAAAAAAAAAQIDBAUGBwgJCgsQAAIBAwMCBAMFBQQEAAABfQECAwAEEQUSITFBBhNRYQcicRQygZGhCCNCscEVUtHwJDNicoIJChYXGBkaJSYnKCkqNDU2Nzg5OkNERUZHSElKU1RVVldYWVpjZGVmZ2hpanN0dXZ3eHl6g4SFhoeIiYqSk5SVlpeYmZqio6Slpqeoqaqys7S1tre4ubrCw8TFxsfIycrS09TV1tfY2drh4uPk5ebn6Onq8fLz9PX29/j5+gEAAwEBAQEBAQEBAQAAAAAAAAECAwQFBgcICQoLEQACAQIEBAMEBwUEBAABAncAAQIDEQQFITEGEkFRB2FxEyIygQgUQpGhscEJIzNS8BVictEKFiQ04SXxFxgZGiYnKCkqNTY3ODk6Q0RFRkdISUpTVFVWV1hZWmNkZWZnaGlqc3R1dnd4eXqCg4SFhoeIiYqSk5SVlpeYmZqio6Slpqeoqaqys7S1tre4ubrCw8TFxsfIycrS09TV1tfY2dri4+Tl5ufo6ery8/T19vf4+fr/2gAMAwEAAhEDEQA/AOvs9L0/7HB/oFr/AKtf+WK+n0qb+y9P/wCfC1/78r/hUtn/AMecH/XNf5VNQB//2Q=="))


# ---- .npy ---------------------------------------------------------------------------------
def npy(descr, shape, payload, version=1, fortran=False):
    shape_text = "(" + ", ".join(str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
    header = ("{'descr': '%s', 'fortran_order': %s, 'shape': %s, }"
              % (descr, "True" if fortran else "False", shape_text))
    prefix = 10 if version == 1 else 12
    total = (prefix + len(header) + 1 + 63) // 64 * 64
    header = header + " " * (total - prefix - len(header) - 1) + "\n"
    size = struct.pack("<H", len(header)) if version == 1 else struct.pack("<I", len(header))
    return b"\x93NUMPY" + bytes([version, 0]) + size + header.encode() + payload


put("npy", "f4_2x3.npy", npy("<f4", (2, 3), struct.pack("<6f", 0, 0.5, 1, -1, 2, 3)))
put("npy", "f8_2x2x3.npy", npy("<f8", (2, 2, 3), struct.pack("<12d", *range(12))))
put("npy", "f4_v2_1x1.npy", npy("<f4", (1, 1), struct.pack("<f", 7), version=2))
put("npy", "f8_empty_0x6.npy", npy("<f8", (0, 6), b""))
put("npy", "bad_dtype.npy", npy("<i4", (1, 2), struct.pack("<2i", 1, 2)))
put("npy", "bad_fortran.npy", npy("<f4", (1, 2), struct.pack("<2f", 1, 2), fortran=True))
put("npy", "bad_truncated.npy", npy("<f8", (2, 2), struct.pack("<3d", 1, 2, 3)))
put("npy", "bad_rank.npy", npy("<f4", (4,), struct.pack("<4f", 1, 2, 3, 4)))
put("npy", "bad_header.npy", b"\x93NUMPY\x01\x00\x10\x00{'descr': '<f4\n")
put("npy", "bad_big_endian.npy", npy(">f4", (1, 1), struct.pack(">f", 1)))

# ---- regressions: inputs the fuzzers found, minimised (tests/test_errors.cpp, ErrorsFuzz.*) --
# A number beyond double's range escaped parse_scene as nlohmann's out_of_range exception.
put("scene", "regression-number-overflow.json",
    '{"meshes": [{"file": "tetra.obj"}], "cameras": [{"fov": 11e308}]}\n')
# Strings of the document quoted in an error message broke it over several lines.
put("scene", "regression-newline-in-string.json",
    '{"meshes": [{"file": "tetra.obj"}], "cameras": [{"projection": "a\\nb"}]}\n')
put("scene", "regression-newline-in-key.json", '{"meshes": [], "came\\nras": []}\n')
# stb_image returns pixels for a PNM header with a zero height; load_image returned a 3x0 image.
put("image", "regression-pnm-zero-height.pgm", b"P5\n3 0\n255\n")
# stb_image 2.27: a JPEG Huffman table (DHT) whose 16 code counts sum past 256 overflows the
# decoder's table (UBSan: index 257 out of bounds for 'stbi_uc[257]'); the seed JPEG with eight
# bytes of its DHT counts changed.
jpeg = bytearray(base64.b64decode(RGB_4X4_JPG))
jpeg[393:401] = b"\xff\xfe\xfe\xfe\xff\xff\xff\xfb"
put("image", "regression-jpeg-huffman-overflow.jpg", bytes(jpeg))
# stb_image 2.27: a PPM with maxval > 255, loaded with another channel count (1 here), comes
# back converted as 8-bit data but labelled 16-bit: reading it overran the buffer.
put("image", "regression-pnm-16bit-overflow.ppm", b"P6\n1 2\n355\n\xff\xff\x00")
# A 35-byte GIF declaring 18177x17993 pixels: stb_image allocated over 2 GiB.
put("image", "regression-gif-huge.gif", b"GIF89a\x01GIF89a\x01\x00\x01\x008")
# A zero-length IDAT chunk first: stb_image copies it with memcpy(NULL, src, 0), which UBSan
# reports (nonnull-attribute); load_image drops empty IDAT chunks before decoding.
put("image", "regression-png-empty-idat.png", png(2, 2, 16, 0, [b"\x00\x00\xff\xff"] * 2,
                                                  empty_idat=True))
# A second IDAT chunk declaring 1.6 GB in a 100-byte file: stb_image grew its buffer to 2 GiB
# before reading (libFuzzer: out-of-memory, malloc(2147483648)).
put("image", "regression-png-huge-chunk.png",
    png(2, 2, 16, 0, [b"\x00\x00\xff\xff"] * 2)[:-12] + struct.pack(">I", 0x61FFC012) +
    b"IDAT" + b"\x00" * 16)
# A PNG chunk name with a carriage return, quoted by stb_image's error message.
put("image", "regression-png-chunk-name.png", b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\x00\x00\x00\x02"
    b"\x00\x00\x00\x02\x08\x00\x00\x00\x00W\xdd\xb2\x1d\x00\x00\x00\x00IHD\r\x00\x00\x00\x00")
# A header key holding a line break was quoted verbatim in load_npy's error message.
put("npy", "regression-newline-in-key.npy", npy("<f4", (1, 1), struct.pack("<f", 1))
    .replace(b"'fortran_order'", b"'fortran\norder'"))
