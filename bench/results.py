"""Loading what the benchmarks wrote: penumbra_bench's JSON (its case names parsed into
records) and the per-kernel profiles of scripts/bench.sh."""
import json
import os
import re

# The reference point of the render cases: what a case's name leaves out.
REF = {"img": 256, "map": 256, "faces": 1312, "sigma_s": 2.0, "lights": 1, "model": "paper"}
TEXT_KEYS = ("model", "scene", "maps")  # name segments key:value whose value is a word

# exact-dense: the hard exact case at σ_s = measures.DENSE_SIGMA_S, where the products skip
# nothing; accurate: the truncated case of the accurate model (the renderer's default).
PROFILE_MODES = [("none", "truncated"), ("hard", "truncated"), ("hard", "exact"),
                 ("hard", "exact-dense"), ("hard", "gemm"), ("soft", "truncated"),
                 ("hard", "accurate"), ("soft", "accurate")]
# A row of the PENUMBRA_PROFILE=1 table: kernel, device ms, launches.
KERNEL_LINE = re.compile(r"^\s+([A-Za-z_]\w*)\s+(\d+(?:\.\d+)?)\s+(\d+)\s*$")


def kind_of(words):
    """The kind and leading fields of a case from its name's words, or None."""
    if words[0] == "ceiling":
        return dict(kind="ceiling", what=words[1] if len(words) > 1 else "")
    if words[:2] == ["accuracy", "ratio"]:
        return dict(kind="accuracy_ratio", shadows=words[2], sampling=words[3])
    if words[0] == "step":  # a render and its backward in turn (bench_render.cpp, run_step)
        return dict(kind="step", shadows=words[1], sampling=words[2], model="paper")
    if words[0] in ("turnaround", "accuracy"):
        return dict(kind=words[0], pass_=words[1], shadows=words[2], sampling=words[3])
    if words[0] in ("fwd", "bwd"):  # the paper's model unless the name says /model:
        return dict(kind="render", pass_=words[0], shadows=words[1], sampling=words[2],
                    model="paper")
    return None


def parse_name(name):
    """'fwd/hard/exact/img:256/...' → dict of its parts (see bench/bench_*.cpp)."""
    parts = [p for p in name.split("/") if p not in ("manual_time", "real_time")
             and not p.startswith(("iterations:", "repeats:", "min_time:"))]
    rec = {"large": False}
    if parts and parts[0] == "large":
        rec["large"] = True
        parts = parts[1:]
    params = {}
    words = []
    for p in parts:
        if ":" in p:
            k, v = p.split(":", 1)
            params[k] = v if k in TEXT_KEYS else float(v) if k == "sigma_s" else int(v)
        else:
            words.append(p)
    kind = kind_of(words) if words else None
    if kind is None:
        return None
    rec.update(kind)
    rec.update(params)
    return rec


def load(path):
    """(context, records) of a penumbra_bench JSON file."""
    with open(path) as f:
        data = json.load(f)
    records = []
    for b in data.get("benchmarks", []):
        if b.get("run_type", "iteration") != "iteration":
            continue
        rec = parse_name(b["name"])
        if rec is None:
            continue
        rec["name"] = b["name"]
        rec["error"] = b.get("error_message") if b.get("error_occurred") else None
        rec["iterations"] = b.get("iterations", 0)
        for k, v in b.items():
            if isinstance(v, (int, float)) and k not in rec:
                rec[k] = v
        records.append(rec)
    return data.get("context", {}), records


class Results:
    def __init__(self, records):
        self.records = [r for r in records if not r["error"]]
        self.errors = [r for r in records if r["error"]]

    def find(self, kind="render", **want):
        """The one record of `kind` matching `want`; parameters not given take REF's values."""
        keys = dict(REF) if kind == "render" else {}
        keys.update(want)
        for r in self.records:
            if r.get("kind") != kind:
                continue
            if all(r.get(k if k != "pass" else "pass_") == v for k, v in keys.items()):
                return r
        return None

    def render(self, pass_="fwd", **want):
        return self.find("render", pass_=pass_, **want)

    def all(self, kind):
        return [r for r in self.records if r.get("kind") == kind]


def load_profile(path, shadows):
    """One profile file: its kernels per frame, frames and exit status."""
    kernels, status = [], None
    for line in open(path, errors="replace"):
        m = KERNEL_LINE.match(line)
        if m:
            kernels.append((m.group(1), int(m.group(3)), float(m.group(2)) * 1e6))
        elif line.startswith("exit status"):
            status = int(line.split()[-1])
    resolves = sum(n for name, n, _ in kernels if name == "raster_resolve")
    frames = resolves // (1 if shadows == "none" else 2)
    if not frames:
        kernels = []
    return {"kernels": [(name, n / frames, round(ns / frames)) for name, n, ns in kernels],
            "frames": frames, "status": status}


def load_profiles(folder):
    """{(shadows, sampling): {"kernels": [(name, launches, ns)] per frame, "frames": int,
    "status": int}}. A profile sums a case's frames; raster_resolve runs once per view, and a
    frame has one view, or two with a light's shadow map."""
    out = {}
    if not folder:
        return out
    for sh, sa in PROFILE_MODES:
        path = os.path.join(folder, f"profile_fwd_{sh}_{sa}.txt")
        if os.path.exists(path):
            out[(sh, sa)] = load_profile(path, sh)
    return out
