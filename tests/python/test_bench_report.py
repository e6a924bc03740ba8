"""bench/report.py turns the profiles scripts/bench.sh writes into per-frame device times."""
import importlib.util

from conftest import ROOT

spec = importlib.util.spec_from_file_location("report", ROOT / "bench" / "report.py")
report = importlib.util.module_from_spec(spec)
spec.loader.exec_module(report)

# What PENUMBRA_PROFILE=1 prints at exit, among penumbra_bench's own lines: 3 frames of a mode
# with shadows (a camera view and a light view each, so 6 raster_resolve launches).
HARD = """fwd/hard/truncated/img:256/map:256/faces:1312/sigma_s:2/lights:1/manual_time 12.5 ms
penumbra profile (device ms, launches):
  shadow_sample                 15.00      3
  raster_resolve                 6.60      6
exit status 0
"""


def test_profiles_are_per_frame(tmp_path):
    (tmp_path / "profile_fwd_hard_truncated.txt").write_text(HARD)
    (tmp_path / "profile_fwd_none_truncated.txt").write_text("penumbra: error\nexit status 1\n")
    p = report.load_profiles(str(tmp_path))
    hard = p[("hard", "truncated")]
    assert hard["frames"] == 3 and hard["status"] == 0
    assert hard["kernels"] == [("shadow_sample", 1.0, 5000000), ("raster_resolve", 2.0, 2200000)]
    none = p[("none", "truncated")]
    assert none["kernels"] == [] and none["status"] == 1
    assert "unavailable" in report.profile_section(None, p)


# The accurate model's soft case: a light pass and a camera pass per frame, like the paper's.
SOFT_ACCURATE = """penumbra profile (device ms, launches):
  pcf_sample                    40.00      4
  raster_resolve                16.00      8
exit status 0
"""


def test_the_accurate_models_profile_is_a_mode_of_its_own(tmp_path):
    (tmp_path / "profile_fwd_soft_accurate.txt").write_text(SOFT_ACCURATE)
    (tmp_path / "profile_fwd_hard_truncated.txt").write_text(HARD)
    p = report.load_profiles(str(tmp_path))
    assert p[("soft", "accurate")]["frames"] == 4
    text = report.profile_section(None, p)
    assert "| soft / accurate | 14.0 ms | pcf 10.0 ms (71 %), raster 4.00 ms (29 %) |" in text
    assert "the renderer's default" in text
    paper_only = {k: v for k, v in p.items() if k[1] != "accurate"}
    assert "the renderer's default" not in report.profile_section(None, paper_only)


PAGE = "# Page\n\n## First\n\nold one\n\n## Second\n\nkept\n"


def test_replace_section_keeps_the_rest_and_the_mode(tmp_path):
    page = tmp_path / "page.md"
    page.write_text(PAGE)
    page.chmod(0o640)
    report.docfile.replace_section(str(page), ["## First", "", "new one", ""])
    assert page.read_text() == "# Page\n\n## First\n\nnew one\n\n## Second\n\nkept\n"
    assert page.stat().st_mode & 0o777 == 0o640
    report.docfile.replace_section(str(page), ["## Third", "", "added", ""], before="## Second")
    assert page.read_text().index("## Third") < page.read_text().index("## Second")
    assert [p.name for p in tmp_path.iterdir()] == ["page.md"]  # no temporary file left


def test_a_failed_write_leaves_the_old_file_whole(tmp_path):
    page = tmp_path / "page.md"
    page.write_text(PAGE)
    try:
        report.docfile.write_text(str(page), None)  # fails inside the write
    except TypeError:
        pass
    else:
        raise AssertionError("writing None did not fail")
    assert page.read_text() == PAGE
    assert [p.name for p in tmp_path.iterdir()] == ["page.md"]


def test_verdicts_near_the_limit_say_so():
    assert report.verdict(9.0, 10.0) == ("met", "1.11× under the limit")
    assert report.verdict(9.8, 10.0)[1].endswith("(within 5 %: another run may not meet it)")
    assert report.verdict(10.3, 10.0) == (
        "**missed**", "1.03× over the limit (within 5 %: another run may meet it)")
    assert report.verdict(12.0, 10.0) == ("**missed**", "1.20× over the limit")
    assert report.verdict(None, 10.0) == ("not measured", "–")


def test_render_cases_name_their_model_unless_the_papers():
    paper = report.parse_name("bwd/soft/truncated/img:256/map:256/faces:1312/sigma_s:2/"
                              "lights:1/manual_time")
    accurate = report.parse_name("bwd/soft/truncated/img:256/map:256/faces:1312/sigma_s:2/"
                                 "lights:1/model:accurate/manual_time")
    assert paper["model"] == "paper" and accurate["model"] == "accurate"
    for r in (paper, accurate):
        r.update(name="", error=None, ms_median=10.0 if r is paper else 20.0)
    res = report.Results([accurate, paper])
    assert res.render("bwd", shadows="soft")["ms_median"] == 10.0  # the reference: paper
    assert res.render("bwd", shadows="soft", model="accurate")["ms_median"] == 20.0


def test_accuracy_ratio_cases_are_their_own_kind():
    rec = report.parse_name(
        "accuracy/ratio/soft/truncated/img:256/map:256/lights:1/scene:knot_h0.3/manual_time")
    assert rec["kind"] == "accuracy_ratio" and rec["shadows"] == "soft"
    assert rec["scene"] == "knot_h0.3"
    fwd = report.parse_name("accuracy/fwd/soft/truncated/img:256/map:256/faces:1312/sigma_s:0.5/"
                            "lights:1/model:accurate/scene:sphere/manual_time")
    assert fwd["kind"] == "accuracy" and fwd["model"] == "accurate"
    # The same pair at each model's default map is told apart from the equal-map one.
    own = report.parse_name(
        "accuracy/ratio/soft/truncated/img:256/maps:default/lights:1/scene:knot_h0.3/manual_time")
    assert own["maps"] == "default" and "map" not in own
    for r, ratio in ((rec, 1.2), (own, 1.4)):
        r.update(name="", error=None, ms_median=1.0, time_ratio=ratio)
    res = report.Results([own, rec])
    assert report.acc_ratio(res, "knot_h0.3", "soft")["time_ratio"] == 1.2
    assert report.acc_ratio(res, "knot_h0.3", "soft", default_maps=True)["time_ratio"] == 1.4


def test_memory_per_face_is_the_slope_between_the_ends_of_the_sweep():
    recs = []
    for faces, mib in ((1312, 10.0), (5152, 11.0), (100852, 60.0)):
        r = report.parse_name(f"fwd/none/truncated/img:256/map:256/faces:{faces}/sigma_s:2/"
                              "lights:1/manual_time")
        r.update(name="", error=None, ms_median=1.0, device_MiB=mib)
        recs.append(r)
    text = "\n".join(report.memory_lines(report.Results(recs), False, "images"))
    assert "| forward, no shadows | 10.0 | 11.0 | 60.0 |" in text
    per_face = 50.0 * 2 ** 20 / (100852 - 1312)
    assert f"forward, no shadows {report.fmt(per_face)}" in text
    # Cases without the counter (an older run) give no section rather than a table of gaps.
    for r in recs:
        del r["device_MiB"]
    assert report.memory_lines(report.Results(recs), False, "images") == []


def test_backward_quotients_come_from_the_step_cases_where_run():
    name = "{}/hard/truncated/img:256/map:256/faces:1312/sigma_s:2/lights:1/manual_time"
    recs = [report.parse_name(name.format(k)) for k in ("fwd", "bwd", "step")]
    for r, extra in zip(recs, ({"ms_median": 10.0}, {"ms_median": 40.0},
                               {"ms_fwd": 11.0, "ms_bwd": 22.0, "bwd_ratio": 2.0,
                                "ms_median": 33.5})):
        r.update(name="", error=None, **extra)
    assert recs[2]["kind"] == "step" and recs[2]["shadows"] == "hard"
    res = report.Results(recs)
    assert report.bwd_over_fwd(res, "hard", "truncated") == (22.0, 2.0)
    assert report.fwd_plus_bwd(res) == 33.5
    # Without the step case, the separate cases' medians.
    res = report.Results(recs[:2])
    assert report.bwd_over_fwd(res, "hard", "truncated") == (40.0, 4.0)
    assert report.fwd_plus_bwd(res) == 50.0


first_call_spec = importlib.util.spec_from_file_location("first_call",
                                                         ROOT / "bench" / "first_call.py")
first_call = importlib.util.module_from_spec(first_call_spec)
first_call_spec.loader.exec_module(first_call)


def test_the_floor_counts_the_kernels_pocl_compiled_per_program(tmp_path):
    for prog, kernels in (("AB/P1", ["raster_count", "raster_fragments", "raster_resolve"]),
                          ("CD/P2", ["transform_fwd", "face_setup"]), ("CD/P3", [])):
        for k in kernels:
            (tmp_path / prog / k).mkdir(parents=True)
        (tmp_path / prog).mkdir(parents=True, exist_ok=True)
        (tmp_path / prog / "program.bc").write_text("")
    (tmp_path / "tempfile_x").write_text("")
    assert first_call.program_kernels(str(tmp_path)) == [3, 2]


def test_the_floor_paragraph_quotes_the_median_run_and_judges_it_against_a_second():
    floor = {"kernels": [3, 2], "command": "penumbra_bench --build-floor 3,2",
             "programs_ms": [[700.0, 200.0], [650.0, 150.0], [900.0, 300.0]]}
    text = " ".join(first_call.floor_paragraph(floor))
    assert "took 900 ms (median of 3 runs, 800–1,200; the first program 700 ms" in text
    assert "`penumbra_bench --build-floor 3,2`" in text
    assert "leaves 100 ms of a second" in text and "cannot take" not in text
    slow = dict(floor, programs_ms=[[800.0, 400.0]])
    text = " ".join(first_call.floor_paragraph(slow))
    assert "cannot take under a second" in text and "leaves" not in text
    assert first_call.floor_paragraph(None) == []


def test_the_first_call_section_names_the_machine_it_ran_on():
    rows = [{"from_source": 4, "from_cache": 0, "build_ms": 900.0, "render_ms": 950.0,
             "process_s": 1.0}]
    doc = {"runs": 1, "date": "2026-12-07T16:00:00+00:00", "command": "penumbra render",
           "loadavg_before": "0.1 0.1 0.1", "loadavg_after": "0.2 0.1 0.1", "floor": None,
           "states": {state: rows for state in first_call.STATES}}
    text = " ".join(first_call.section(doc))
    assert "the median of 1 runs (`bench/first_call.py`" in text
    text = " ".join(first_call.section(dict(doc, cpu="AMD EPYC", cores=2)))
    assert "the median of 1 runs on AMD EPYC, 2 cores (`bench/first_call.py`" in text


def test_kernels_are_judged_against_the_ceiling_their_work_has():
    name = "fwd/hard/{}/img:256/map:256/faces:1312/sigma_s:{}/lights:1/manual_time"
    trunc, dense = (report.parse_name(name.format(*a)) for a in (("truncated", 2), ("exact", 400)))
    trunc.update(name="", error=None, ms_median=8.0, fragments=1000.0, samples_per_s=1e9)
    dense.update(name="", error=None, ms_median=50.0, fragments=1000.0)
    res = report.Results([trunc, dense])
    profiles = {("hard", "truncated"): {"frames": 2, "status": 0, "kernels": [
                    ("shadow_sample", 1.0, 4e6), ("raster_count", 2.0, 1e6)]},
                ("hard", "exact-dense"): {"frames": 2, "status": 0, "kernels": [
                    ("matmul_nn_rowdot", 1.0, 2.0 * 1000 * 256 * 256 / 100.0),
                    ("exact_weights", 1.0, 1000 * 2 * 256 / 5.0)]}}
    text = report.profile_section(res, profiles, peak=200.0, exp_rate=10e9)
    # 8 M samples a frame in 4 ms; 131 MFLOP in 1.31 ms; 512 k exps in 102 µs.
    assert "`shadow_sample` 2 G samples/s = 20 % of exp rate" in text
    assert "`matmul_nn_rowdot` 100 GFLOP/s = 50 % of FMA peak" in text
    assert "`exact_weights` ≤ 5 G exp/s = 50 % of exp rate" in text
    assert abs(report.matmul_rate(res, profiles, dense=True)[0] - 100.0) < 1e-9  # the same count
    row = next(line for line in text.splitlines() if line.startswith("| hard / truncated"))
    assert "raster_count" not in row.split("|")[5]  # the raster's kernels have no one ceiling
    # Where the products skip zero weights, a dense-equivalent rate and no share of the peak.
    assert "dense-equivalent" in report.kernel_rates(trunc, [("matmul_nn_rowdot", 1, 1e6)], 200.0,
                                                     10e9)
