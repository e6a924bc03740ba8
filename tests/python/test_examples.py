"""examples/python/fit_shadow.py runs, converges to the target's shape and writes its picture."""
import re
import subprocess
import sys

from conftest import ROOT


def test_fit_shadow(tmp_path):
    r = subprocess.run([sys.executable, str(ROOT / "examples" / "python" / "fit_shadow.py")],
                       cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stderr == ""  # no warnings, no leak reports
    m = re.search(r"loss=(\S+) scale=\[(\S+), (\S+)\] shift=\[(\S+), (\S+)\]", r.stdout)
    loss, sx, sz, dx, dz = map(float, m.groups())
    assert loss < 1e-4
    assert abs(sx - 1.4) < 0.02 and abs(sz - 0.7) < 0.02
    assert abs(dx - 0.3) < 0.02 and abs(dz + 0.2) < 0.02
    assert (tmp_path / "fit_shadow.png").stat().st_size > 0
    assert len((ROOT / "examples" / "python" / "fit_shadow.py").read_text().splitlines()) <= 40


def test_deform_to_shadows(tmp_path):
    script = ROOT / "examples" / "python" / "deform_to_shadows.py"
    r = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "warning" not in r.stderr  # the frusta follow the shape as it deforms
    m = re.search(r"shadow error (\S+) at the start, (\S+) fitted", r.stdout)
    start, fitted = map(float, m.groups())
    assert fitted < start / 100
    assert (tmp_path / "deform_to_shadows.png").stat().st_size > 0
    assert len(script.read_text().splitlines()) <= 65
