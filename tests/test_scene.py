"""Scene model: built-in procedural scenes, YAML scenes with mesh files, validation errors naming the field."""

from __future__ import annotations

import numpy as np
import pytest

from renderers.catalog import builtin, resolve
from renderers.scene import Camera, Material, Scene, SceneError, load_yaml


@pytest.mark.parametrize("name,lights", [("cornell", 18), ("temple", 31), ("street_night", 12),
                                         ("interior", 21), ("street_day", 1)])
def test_builtin_scenes(name, lights):
    sc = builtin(name)
    assert sc.light_count() == lights
    assert sc is builtin(name)  # cached
    assert np.isfinite(sc.vertices).all() and sc.faces.max() < len(sc.vertices)
    if name == "temple":
        assert sc.n_triangles >= 500_000
    if name == "street_day":
        assert len(sc.directional_lights) == 1 and not sc.point_lights
    textures = {m.texture for m in sc.materials}
    assert textures & {"checker", "brick", "noise"}


def test_content_hash_changes_with_content():
    from renderers.procedural import cornell

    a = builtin("cornell")
    b = cornell()  # a fresh copy, not the cached built-in
    assert a.content_hash() == b.content_hash()
    b.materials[0] = Material("white", albedo=(0.7, 0.73, 0.73))
    b._hash = None
    assert a.content_hash() != b.content_hash()


def _write_yaml(tmp_path, text):
    p = tmp_path / "scene.yaml"
    p.write_text(text)
    return p


GOOD = """
name: yaml_test
materials:
  floor: {albedo: [0.8, 0.8, 0.8], albedo2: [0.1, 0.1, 0.1], texture: checker, texture_scale: 0.5}
  box: {albedo: [0.6, 0.3, 0.2], kind: glossy, roughness: 0.3}
meshes:
  - {file: floor.ply, material: floor}
  - {file: cube.stl, material: box, translate: [0.5, 0, 0]}
lights:
  - {type: point, position: [0, 3, 0], intensity: [5, 5, 5]}
camera: {position: [0, 1.5, -3], look_at: [0, 0.5, 1], up: [0, 1, 0], fov_y: 50}
display: {width: 64, height: 48}
"""


def test_yaml_scene_loads_and_renders(mesh_file):
    p = mesh_file / "scene.yaml"
    p.write_text(GOOD)
    sc = load_yaml(p)
    assert sc.name == "yaml_test" and sc.n_triangles == 8 + 12
    assert [m.name for m in sc.materials] == ["floor", "box"]
    assert np.bincount(sc.material_ids).tolist() == [8, 12]
    from renderers import render

    img, st = render(str(p), "gt", {}, 64, 48)
    assert img.shape == (48, 64, 3) and st["shading_points"] > 0 and img.max() > 0.05


@pytest.mark.parametrize("change,match", [
    (("cube.stl", "missing.stl"), r"bad\.yaml:\d+: meshes\[1\]\.file: mesh file .*missing\.stl' does not exist"),
    (("kind: glossy", "kind: shiny"), r"bad\.yaml:\d+: materials\.box\.kind: 'shiny' is not one of"),
    (("fov_y: 50", "fov_y: 200"), r"bad\.yaml:\d+: camera\.fov_y: 200 must be less than 180"),
    (("material: box", "material: wood"), r"bad\.yaml:\d+: meshes\[1\]\.material: 'wood' is not defined"),
    (("intensity: [5, 5, 5]", "intensity: [5, 5]"), r"bad\.yaml:\d+: lights\[0\]\.intensity: needs at least 3"),
    (("camera:", "camra:"), r"bad\.yaml:\d+: camra: unknown field"),
    (("width: 64", "width: -3"), r"bad\.yaml:\d+: display\.width: -3 is below the minimum 1"),
    (("type: point", "type: spot"), r"bad\.yaml:\d+: lights\[0\]\.type: 'spot' is not one of point, directional"),
    (("fov_y: 50}", "fov_y: 50, focus: 2}"), r"bad\.yaml:\d+: camera\.focus: unknown field"),
])
def test_yaml_errors_name_the_file_line_and_field(mesh_file, change, match):
    p = mesh_file / "bad.yaml"
    p.write_text(GOOD.replace(*change))
    with pytest.raises(SceneError, match=match) as exc:
        load_yaml(p)
    assert "\n" not in str(exc.value)


def test_yaml_malformed_and_no_lights(mesh_file):
    p = mesh_file / "broken.yaml"
    p.write_text("meshes: [ {file: floor.ply\nlights: ]")
    with pytest.raises(SceneError, match=r"broken\.yaml:2: malformed YAML"):
        load_yaml(p)
    p.write_text(GOOD.replace("  - {type: point, position: [0, 3, 0], intensity: [5, 5, 5]}\n", ""))
    with pytest.raises(SceneError, match=r"broken\.yaml:\d+: lights: the scene has no point, directional or emissive"):
        load_yaml(p)


def test_resolve_errors():
    with pytest.raises(ValueError, match="neither a built-in scene"):
        resolve("no_such_scene")
    sc = Scene("dark", [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], [0], [Material()])
    with pytest.raises(ValueError, match="has no lights"):
        resolve(sc)


def test_camera_override_and_eyes():
    cam = Camera((0, 0, 0), (0, 0, 1), (0, 1, 0), 60)
    assert cam.override({"fov_y": 30}).fov_y == 30
    with pytest.raises(ValueError, match="camera.focus is unknown"):
        cam.override({"focus": 1})
    left, right = cam.eye(-0.032), cam.eye(0.032)
    # right = forward x up = -x for a camera looking +z with +y up
    assert left.position[0] == pytest.approx(0.032) and right.position[0] == pytest.approx(-0.032)
    with pytest.raises(ValueError, match="camera.up"):
        Camera((0, 0, 0), (0, 1, 0), (0, 1, 0), 60)
