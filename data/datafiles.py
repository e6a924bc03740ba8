"""File output shared by the data generators (make_meshes.py, make_targets.py): every file is
written whole to a temporary file next to it and renamed over it, so that a failure leaves the
bundled file as it was."""
import os
import tempfile


def write_atomic(path, data):
    """Write bytes `data` to `path` through a temporary file and a rename."""
    fd, tmp = tempfile.mkstemp(dir=os.path.dirname(path) or ".", prefix=".tmp-")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def write_obj(path, verts, faces, comment):
    """A Wavefront OBJ of vertices (x, y, z) and 0-based triangles, `comment` lines first."""
    lines = ["# %s" % line for line in comment]
    lines.append("# %d vertices, %d faces" % (len(verts), len(faces)))
    lines += ["v %.9g %.9g %.9g" % v for v in verts]
    lines += ["f %d %d %d" % (a + 1, b + 1, c + 1) for a, b, c in faces]
    write_atomic(path, ("\n".join(lines) + "\n").encode())
