"""Protocol files: the shipped replications load with the seeds' designs; bad files give FILE:LINE: FIELD."""

import json
import os
import re
from pathlib import Path

import pytest

from data_schema.protocol_schema import ProtocolError, load_schema
from studyapp.runner.protocol import load_protocol
from studyapp.runner.schedule import build_schedule

ROOT = Path(__file__).resolve().parents[1]
PROTOCOLS = ROOT / "protocols"
SHIPPED = sorted(PROTOCOLS.glob("seed*.yaml"))


def test_the_replication_protocols_are_shipped():
    assert [p.stem for p in SHIPPED] == ["seed001_2afc", "seed001_2afc_live", "seed001_pilot", "seed001_pilot_live",
                                         "seed003_alpha_threshold", "seed003_task1", "seed003_task1_live",
                                         "seed003_task2", "seed003_task2_live"]


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_shipped_protocols_validate_and_state_their_render_budget(path):
    p = load_protocol(path, check_renderers=False)
    # pre-rendered sets state what preparing them costs; live ones that nothing is prepared
    assert ("Nothing is prepared" if p.live else "30 min") in p.data["render_budget"]
    assert p.content_hash == load_protocol(path, check_renderers=False).content_hash
    assert re.fullmatch(r"[0-9a-f]{64}", p.content_hash)


def test_seed001_designs():
    pilot = load_protocol(PROTOCOLS / "seed001_pilot.yaml", check_renderers=False)
    assert pilot.family == "preference" and pilot.n_picks == 2
    assert pilot.design_conditions == ("VaFR_Rep", "VaFR_Dup", "LaFR(2.2)", "LaFR(1.8)", "GT")
    assert len(pilot.scenes) == 3
    two = load_protocol(PROTOCOLS / "seed001_2afc.yaml", check_renderers=False)
    sched = build_schedule(two, "P1", 0)
    main = [t for t in sched if t.kind == "trial"]
    assert len(main) == 90  # 10 pairs x 3 repetitions x 3 scenes (seed: 30 trials per scene)
    for scene in two.scenes:
        assert sum(t.scene == scene for t in main) == 30


@pytest.mark.parametrize("name", ["seed001_pilot", "seed001_2afc"])
def test_seed001_live_replications_keep_the_pre_rendered_designs(name):
    """Same family, conditions, scenes and schedule as the pre-rendered replication; explored live at the
    display's native resolution with the renderers' GPU versions (checked: check_renderers=True)."""
    pre = load_protocol(PROTOCOLS / f"{name}.yaml", check_renderers=False)
    live = load_protocol(PROTOCOLS / f"{name}_live.yaml", check_renderers=True)
    assert live.live and live.motion == "explore" and live.data["stimulus"]["gaze"] == "tracker"
    assert (live.family, live.design_conditions, live.scenes) == (pre.family, pre.design_conditions, pre.scenes)
    assert set(live.scenes) == {"street_night", "interior", "temple"}
    g = live.render_geometry()
    assert (g.width, g.height) == (live.display.width_px, live.display.height_px)  # native resolution
    assert {live.backend_of(c) for c in live.conditions} == {"gpu"}
    kinds = lambda p: [t.kind for t in build_schedule(p, "P1", 0)]  # noqa: E731
    assert kinds(live).count("trial") == kinds(pre).count("trial")


def test_seed003_designs():
    t1 = load_protocol(PROTOCOLS / "seed003_task1.yaml", check_renderers=False)
    assert (t1.duration_s, t1.black_s, t1.reference) == (8.0, 0.5, "CC1")
    assert t1.design_conditions == ("EC", "CC1", "CC2", "CC3", "CC4")
    s1 = build_schedule(t1, "P1", 0)
    assert sum(t.kind == "trial" for t in s1) == 50
    t2 = load_protocol(PROTOCOLS / "seed003_task2.yaml", check_renderers=False)
    assert (t2.duration_s, t2.black_s) == (16.0, 1.0)
    assert t2.design_conditions == ("EC", "CC2", "CC3", "CC4")
    assert sum(t.kind == "trial" for t in build_schedule(t2, "P1", 0)) == 40


@pytest.mark.parametrize("name,motion", [("seed003_task1", "path"), ("seed003_task2", "explore")])
def test_seed003_live_replications_keep_the_pre_rendered_designs(name, motion):
    """Seed 003's tasks live: the same family, design conditions, scenes, timing and schedule as the pre-rendered
    replication; animations (Task 1) or explorations (Task 2) at the display's native resolution on the GPU
    versions of the lightcuts renderers (checked: check_renderers=True); no condition's frame rate is capped, and
    CC1 is the ground truth with the seed's 2048 + 2048 samples."""
    from renderers.registry import resolve_params

    pre = load_protocol(PROTOCOLS / f"{name}.yaml", check_renderers=False)
    live = load_protocol(PROTOCOLS / f"{name}_live.yaml", check_renderers=True)
    assert live.live and live.motion == motion and live.data["stimulus"]["gaze"] == "tracker"
    assert (live.family, live.design_conditions, live.scenes) == (pre.family, pre.design_conditions, pre.scenes)
    assert (live.duration_s, live.black_s, live.reference) == (pre.duration_s, pre.black_s, pre.reference)
    g = live.render_geometry()
    assert (g.width, g.height) == (live.display.width_px, live.display.height_px)
    assert {live.backend_of(c) for c in live.conditions} == {"gpu"}
    assert all(c.max_fps is None and c.latency_ms == 0 for c in live.conditions.values())
    gt = live.conditions["CC1"]
    assert gt.renderer == "sl_gt" and resolve_params("sl_gt", gt.params)["lspp"] == 2048
    kinds = lambda p: [t.kind for t in build_schedule(p, "P1", 0)]  # noqa: E731
    assert kinds(live).count("trial") == kinds(pre).count("trial") == (50 if motion == "path" else 40)


def test_ppd_from_display_geometry():
    p = load_protocol(PROTOCOLS / "seed003_task1.yaml", check_renderers=False)
    d = p.display
    # 1920 px over 53 cm seen from 45 cm: px per cm * cm per degree at the centre.
    assert d.ppd == pytest.approx(1920 / 53.0 * 45.0 * 0.017455064928217585, rel=1e-12)
    # the 256x144 render covers the display: the same visual angle, fewer pixels per degree
    assert p.render_geometry().fov_y_deg == pytest.approx(d.fov_y_deg) and p.render_size == (256, 144)
    assert p.render_geometry().ppd == pytest.approx(d.ppd * 256 / 1920, rel=1e-12)


def test_display_angle_stated_must_agree_and_render_aspect_must_match(tmp_path):
    text = (PROTOCOLS / "seed003_task1.yaml").read_text()
    f = _write(tmp_path, text.replace("refresh_hz: 60}", "refresh_hz: 60, fov_y_deg: 60}", 1))
    with pytest.raises(ProtocolError, match=r"display\.fov_y_deg: 60° disagrees with the display's size.*36\.65°"):
        load_protocol(f, check_renderers=False)
    f = _write(tmp_path, text.replace("refresh_hz: 60}", "refresh_hz: 60, fov_y_deg: 36.65}", 1))
    assert load_protocol(f, check_renderers=False).display.fov_y_deg == pytest.approx(36.655, abs=1e-3)
    f = _write(tmp_path, text.replace("render_px: [256, 144]", "render_px: [256, 256]", 1))
    with pytest.raises(ProtocolError, match=r"stimulus\.render_px: 256x256 has not the display's aspect ratio"):
        load_protocol(f, check_renderers=False)


def test_a_renderer_that_cannot_render_for_the_display_is_refused_at_validation(tmp_path):
    """LaFR's defaults are undefined on a tall, narrow display (its foveal share would leave (0, 1)): refused
    when the protocol is validated, with the reason, not when a participant is waiting."""
    text = (PROTOCOLS / "seed001_2afc.yaml").read_text().replace(
        "display: {width_px: 1920, height_px: 1080, width_cm: 53.0, distance_cm: 45.0, refresh_hz: 60}",
        "display: {width_px: 64, height_px: 3338, width_cm: 1.0, distance_cm: 100.84, refresh_hz: 60}").replace(
        "render_px: [960, 540]", "render_px: [64, 3338]")
    f = _write(tmp_path, text)
    with pytest.raises(ProtocolError, match=r"conditions\.LaFR\(2\.2\)\.renderer: lafr cannot render for this "
                       r"display \(64x3338 px, 29\.0°\): lafr\.alpha=0\.85 is out of range"):
        load_protocol(f)


def test_schema_file_is_json_schema_and_the_shipped_files_pass_it():
    schema = json.loads((ROOT / "data_schema" / "protocol.schema.json").read_text())
    assert schema["$schema"].startswith("https://json-schema.org/")
    import jsonschema
    import yaml

    from data_schema.yamlfile import _Loader
    jsonschema.Draft202012Validator.check_schema(schema)
    for path in SHIPPED:
        data = yaml.load(path.read_text(), Loader=_Loader)
        assert list(jsonschema.Draft202012Validator(schema).iter_errors(data)) == []


BASE = PROTOCOLS / "seed003_task2.yaml"


def _write(tmp_path, text, name="p.yaml"):
    f = tmp_path / name
    f.write_text(text)
    return f


def _edit(tmp_path, old, new):
    text = BASE.read_text()
    assert old in text
    return _write(tmp_path, text.replace(old, new, 1))


def _line_of(path, needle):
    for i, line in enumerate(Path(path).read_text().splitlines(), 1):
        if needle in line:
            return i
    raise AssertionError(needle)


@pytest.mark.parametrize("old,new,needle,field,words", [
    ("repetitions: 2", "repetitions: 0", "repetitions: 0", "design.repetitions", "below the minimum 1"),
    ("repetitions: 2", "repetitions: two", "repetitions: two", "design.repetitions", "not of type integer"),
    ("  max_run: 2", "  max_runs: 2", "max_runs", "design.max_runs", "unknown field"),
    ("family: yes_no", "family: rating", "family: rating", "family", "not one of"),
    ("distance_cm: 45.0", "distance_cm: -45.0", "distance_cm: -45.0", "display.distance_cm", "greater than 0"),
    ("conditions: [EC, CC2, CC3, CC4]", "conditions: [EC, CC2, CC9]", "conditions: [EC, CC2, CC9]",
     "design.conditions[2]", "unknown condition 'CC9'"),
    ("  reference: EC", "  reference: GT", "reference: GT", "analysis.reference", "unknown condition 'GT'"),
    ("fixation: {x: 0.5, y: 0.5}", "fixation: {x: 1.5, y: 0.5}", "fixation:", "fixation.x", "above the maximum"),
    ("catch: {count: 4, kind: degraded, good: CC1, bad: DEGRADED",
     "catch: {count: 4, kind: degraded, good: CC1, bad: BLURRED", "catch:", "catch.bad", "unknown condition"),
    ("  dv: response", "  dv: chosen", "dv: chosen", "analysis.dv", "record 'response'"),
])
def test_bad_fields_name_file_line_and_field(tmp_path, old, new, needle, field, words):
    f = _edit(tmp_path, old, new)
    with pytest.raises(ProtocolError) as info:
        load_protocol(f, check_renderers=False)
    msg = str(info.value)
    assert "\n" not in msg
    assert msg.startswith(f"{f}:{_line_of(f, needle)}: {field}: "), msg
    assert words in msg


def test_missing_required_field_and_malformed_yaml(tmp_path):
    f = _write(tmp_path, BASE.read_text().replace("question:", "questions:", 1))
    with pytest.raises(ProtocolError, match=r"p\.yaml:\d+: (questions: unknown field|missing required field 'question')"):
        load_protocol(f, check_renderers=False)
    f = _write(tmp_path, "name: x\nscenes: [a, b\nfamily: yes_no\n")
    with pytest.raises(ProtocolError, match=r"p\.yaml:\d+: malformed YAML"):
        load_protocol(f)
    f = _write(tmp_path, "- just\n- a list\n")
    with pytest.raises(ProtocolError, match=r"p\.yaml:1: a protocol must be a YAML mapping"):
        load_protocol(f)
    with pytest.raises(ProtocolError, match="no such protocol file"):
        load_protocol(tmp_path / "none.yaml")


def test_duplicate_keys_are_errors_not_silently_overwritten(tmp_path):
    text = BASE.read_text().replace("timing: {black_s: 1.0}", "timing: {black_s: 1.0}\ntiming: {black_s: 2.0}")
    f = _write(tmp_path, text)
    with pytest.raises(ProtocolError) as info:
        load_protocol(f, check_renderers=False)
    assert str(info.value) == f"{f}:{_line_of(f, 'black_s: 2.0')}: timing: duplicate key"


def test_yes_no_answers_stay_strings(tmp_path):
    f = _edit(tmp_path, "timing: {black_s: 1.0}", "timing: {black_s: 1.0}\nkeys: {answer: {y: yes, n: no}}")
    p = load_protocol(f, check_renderers=False)
    assert p.answer_keys == {"y": "yes", "n": "no"}


def test_condition_needs_exactly_one_source(tmp_path):
    f = _edit(tmp_path, "CC3: {renderer: sl_as,", "CC3: {folder: x, renderer: sl_as,")
    with pytest.raises(ProtocolError, match=r"conditions\.CC3: give exactly one of renderer, folder or derive"):
        load_protocol(f, check_renderers=False)


def test_renderer_names_and_parameters_are_checked_against_the_registry(tmp_path):
    text = (PROTOCOLS / "seed001_2afc.yaml").read_text()
    f = _write(tmp_path, text.replace("{renderer: gt,", "{renderer: gtx,", 1))
    with pytest.raises(ProtocolError) as info:
        load_protocol(f)
    assert f"{f}:{_line_of(f, 'renderer: gtx')}: conditions.GT.renderer: unknown renderer 'gtx'" in str(info.value)
    f = _write(tmp_path, text.replace("params: {delta: 2.2}", "params: {delta: 0.5}", 1))
    with pytest.raises(ProtocolError, match=r"conditions\.LaFR\(2\.2\)\.params: lafr\.delta=0\.5 is out of range"):
        load_protocol(f)
    assert load_protocol(PROTOCOLS / "seed001_2afc.yaml").conditions["VaFR_Rep"].params == {"stereo": "rep"}


def test_validate_command_exit_codes(tmp_path, capsys):
    from studyapp.commands.study import main

    assert main(["validate", str(PROTOCOLS / "seed001_pilot.yaml")]) == 0
    out = capsys.readouterr().out
    assert "valid" in out and "3 trial" in out and "1 practice" in out
    f = _edit(tmp_path, "repetitions: 2", "repetitions: 0")
    assert main(["validate", str(f)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"studyapp: error: {f}:")
    assert os.path.exists(f)


def test_schema_describes_every_top_level_field():
    schema = load_schema()
    top = schema["properties"]
    assert {"display", "conditions", "design", "analysis", "practice", "breaks", "catch", "timing"} <= set(top)
    assert set(schema["$defs"]["analysis"]["required"]) == {"dv", "unit", "test"}


def test_a_pre_rendered_stimulus_over_the_image_limit_is_refused_at_validation(tmp_path):
    """Stimulus PNGs are read back through data_schema.images (at most 8192 x 8192 pixels): a render size over
    that would be prepared for hours, then refused at the first trial; validation names the field instead."""
    text = (PROTOCOLS / "seed001_2afc.yaml").read_text()
    assert "render_px: [960, 540]" in text
    with pytest.raises(ProtocolError, match=r"p\.yaml:\d+: stimulus\.render_px: 15360x8640 pixels is over the limit of "
                                        r"8192x8192 \(67 M pixels\)"):
        load_protocol(_write(tmp_path, text.replace("render_px: [960, 540]", "render_px: [15360, 8640]", 1)),
                      check_renderers=False)
    big_display = text.replace("width_px: 1920, height_px: 1080", "width_px: 16384, height_px: 9216", 1)
    assert load_protocol(_write(tmp_path, big_display, "ok.yaml"), check_renderers=False).render_size == (960, 540)
