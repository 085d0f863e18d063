"""A sidecar's "order" entry (version 6): where a headset eye's order was sorted from,
culled for and coloured from. Its exact round trip, its strict loading, the versions of
files without it, and ``render --sidecar`` drawing that order to the bit (and tiles
sharing its colour origin)."""

from __future__ import annotations

import copy
import dataclasses
import json

import numpy as np
import pytest
from testkit import (
    SETTINGS,
    assert_differs,
    assert_matches,
    assert_one_line_error,
    assert_user_error,
    delete_field,
    demo_sidecar,
    listing,
    run_cli,
    set_field,
    window_camera,
    write_case,
)

from raygs_viewer.camera.pinhole import Camera, look_at
from raygs_viewer.camera.stereo import StereoRig, StereoView
from raygs_viewer.capture.camera_entries import OrderViewpoint, viewpoint_entry
from raygs_viewer.capture.image_io import encode_image
from raygs_viewer.capture.screenshot import render_tiled, save_screenshot
from raygs_viewer.capture.sidecar import VIEWPOINT_SIDECAR_VERSION, load_sidecar
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.sort.depth import DepthSorter

#: The image: the left eye, an arbitrary float64 pose with fx != fy, off-centre.
EYE = window_camera(64, 48)
#: The other eye: its centre moved along the eye's +x by an IPD with digits JSON must keep.
OTHER_EYE = dataclasses.replace(EYE, t=EYE.t - np.array([0.0631234567890123, 0.0, 0.0]))
#: The sort's camera, far from the eye: behind the scene, looking back at it through a
#: narrow lens (its own frustum keeps much less than the eyes see), another size and fx.
SORT = look_at([0.4 + 1e-12, -0.9, 9.5 + 1.0 / 3], [0.1, 0.2, 0.3], width=80, height=60, fov_y_degrees=25.0)
#: Where the SH colour was evaluated from: far from the eye, off every axis.
ORIGIN = np.array([2.5 + 1e-13, -1.0 / 3, 6.0 / 7])

HEADSET = OrderViewpoint(SORT, (EYE, OTHER_EYE), ORIGIN)


def headset_sidecar(viewpoint=HEADSET, **kwargs):
    return demo_sidecar(camera=EYE, viewpoint=viewpoint, **kwargs)


def write_json(path, data):
    path.write_text(json.dumps(data, indent=2))
    return path


def assert_same_bits(a: Camera, b: Camera):
    assert (a.width, a.height) == (b.width, b.height)
    for name in ("fx", "fy", "cx", "cy"):
        assert float(getattr(a, name)).hex() == float(getattr(b, name)).hex(), name
    assert a.R.dtype == b.R.dtype == np.float64 and a.t.dtype == b.t.dtype == np.float64
    assert a.R.tobytes() == b.R.tobytes() and a.t.tobytes() == b.t.tobytes()


# --------------------------------------------------------------------------- writing and reading


def test_round_trip_keeps_every_bit(tmp_path):
    data = headset_sidecar()
    assert data["version"] == VIEWPOINT_SIDECAR_VERSION == 6
    assert set(data["order"]) == {"sorted_from", "culled_for", "colour_from"}
    assert data["order"]["sorted_from"]["width"] == 80 and len(data["order"]["culled_for"]) == 2
    assert data["order"]["sorted_from"]["world_to_camera"] == {"R": SORT.R.tolist(), "t": SORT.t.tolist()}
    # Through the window's writer (the JSON text it saves), not json.dumps alone.
    _, js = save_screenshot(np.zeros((48, 64, 4), np.float32), data, folder=tmp_path)
    loaded = load_sidecar(js)
    assert_same_bits(loaded.camera, EYE)
    viewpoint = loaded.viewpoint
    assert isinstance(viewpoint, OrderViewpoint)
    assert_same_bits(viewpoint.camera, SORT)
    assert len(viewpoint.cull_cameras) == 2
    for got, written in zip(viewpoint.cull_cameras, (EYE, OTHER_EYE)):
        assert_same_bits(got, written)
    assert viewpoint.color_origin.dtype == np.float64 and viewpoint.color_origin.shape == (3,)
    assert viewpoint.color_origin.tobytes() == ORIGIN.tobytes()
    # The eyes differ in their last bits only where written so: the test's cameras are distinct.
    assert OTHER_EYE.t.tobytes() != EYE.t.tobytes()


def test_null_cull_and_colour_round_trip_as_none(tmp_path):
    data = headset_sidecar(OrderViewpoint(SORT))
    assert data["order"]["culled_for"] is None and data["order"]["colour_from"] is None
    viewpoint = load_sidecar(write_json(tmp_path / "shot.json", data)).viewpoint
    assert viewpoint.cull_cameras is None and viewpoint.color_origin is None
    assert_same_bits(viewpoint.camera, SORT)


def test_a_file_without_order_keeps_its_version(tmp_path):
    """"order" is written only when there is one, so older readers keep reading the rest."""
    plain = demo_sidecar()
    assert plain["version"] == 1 and "order" not in plain
    assert load_sidecar(write_json(tmp_path / "plain.json", plain)).viewpoint is None
    stereo = demo_sidecar(stereo=StereoView(StereoRig(), "sbs"))
    assert stereo["version"] == 2 and "order" not in stereo
    edits = {"format": "raygs-viewer edits", "version": 1, "scene": {}, "operations": []}
    assert demo_sidecar(edits=edits)["version"] == 5
    assert headset_sidecar(edits=edits)["version"] == 6


def test_a_stereo_image_records_no_viewpoint(tmp_path):
    with pytest.raises(ValueError, match="stereo"):
        demo_sidecar(stereo=StereoView(StereoRig(), "sbs"), viewpoint=HEADSET)
    data = demo_sidecar(stereo=StereoView(StereoRig(), "sbs"))
    data["order"], data["version"] = viewpoint_entry(HEADSET), 6
    path = write_json(tmp_path / "pair.json", data)
    assert_user_error(lambda: load_sidecar(path), path, "'order'", "'stereo'", "mono")


def test_the_viewpoint_checks_its_values():
    with pytest.raises(ValueError, match="shape"):
        OrderViewpoint(SORT, None, np.zeros(2))
    with pytest.raises(ValueError, match="cull_cameras"):
        OrderViewpoint(SORT, ())
    origin = ORIGIN.copy()
    viewpoint = OrderViewpoint(SORT, [EYE], origin)
    origin[0] = 99.0  # the caller's array changes; the frozen value does not
    assert viewpoint.color_origin[0] == ORIGIN[0] and viewpoint.cull_cameras == (EYE,)


ROTATION_SCALED = [[2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]]

MALFORMED_ORDER = {
    # case: (mutation of a valid headset sidecar, fragment of the message)
    "old_version": (set_field("version", 5), "'order' needs sidecar version 6"),
    "order_list": (set_field("order", []), "'order'"),
    "order_unknown_key": (set_field("order.sorted_by", "midpoint"), "unknown field 'order.sorted_by'"),
    "sorted_from_missing": (delete_field("order.sorted_from"), "missing 'order.sorted_from'"),
    "culled_for_missing": (delete_field("order.culled_for"), "missing 'order.culled_for'"),
    "colour_from_missing": (delete_field("order.colour_from"), "missing 'order.colour_from'"),
    "sorted_from_null": (set_field("order.sorted_from", None), "'order.sorted_from'"),
    "sorted_from_unknown_key": (set_field("order.sorted_from.k1", 0.1), "unknown field 'order.sorted_from.k1'"),
    "sorted_from_no_pose": (delete_field("order.sorted_from.world_to_camera"),
                            "missing 'order.sorted_from.world_to_camera'"),
    "sorted_from_pose_list": (set_field("order.sorted_from.world_to_camera", [1, 2]),
                              "'order.sorted_from.world_to_camera'"),
    "pose_unknown_key": (set_field("order.sorted_from.world_to_camera.s", 1.0),
                         "unknown field 'order.sorted_from.world_to_camera.s'"),
    "sorted_from_fx_negative": (set_field("order.sorted_from.fx", -3.0), "fx"),
    "sorted_from_fx_string": (set_field("order.sorted_from.fx", "70"), "'order.sorted_from': 'fx'"),
    "sorted_from_cx_nan": (set_field("order.sorted_from.cx", float("nan")), "'cx'"),
    "sorted_from_R_scaled": (set_field("order.sorted_from.world_to_camera.R", ROTATION_SCALED),
                             "'order.sorted_from.world_to_camera.R' is not a rotation"),
    "sorted_from_R_mirror": (set_field("order.sorted_from.world_to_camera.R",
                                       [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]), "not a rotation"),
    "sorted_from_rotation_scaled": (set_field("order.sorted_from.rotation", ROTATION_SCALED), "rotation"),
    "sorted_from_t_inf": (set_field("order.sorted_from.world_to_camera.t", [0.0, float("inf"), 0.0]),
                          "'order.sorted_from.world_to_camera.t'"),
    "sorted_from_t_bool": (set_field("order.sorted_from.world_to_camera.t", [True, 0.0, 0.0]),
                           "'order.sorted_from.world_to_camera.t'"),
    "sorted_from_pose_disagrees": (set_field("order.sorted_from.position", [9.0, 9.0, 9.0]), "different poses"),
    "culled_for_object": (set_field("order.culled_for", {"left": 1}), "'order.culled_for'"),
    "culled_for_empty": (set_field("order.culled_for", []), "'order.culled_for' must list"),
    "culled_for_number": (set_field("order.culled_for.1", 3), "'order.culled_for[1]'"),
    "culled_for_unknown_key": (set_field("order.culled_for.0.lens", "fisheye"),
                               "unknown field 'order.culled_for[0].lens'"),
    "culled_for_R_scaled": (set_field("order.culled_for.1.world_to_camera.R", ROTATION_SCALED),
                            "'order.culled_for[1].world_to_camera.R' is not a rotation"),
    "culled_for_t_nan": (set_field("order.culled_for.1.world_to_camera.t", [float("nan"), 0.0, 0.0]),
                         "'order.culled_for[1].world_to_camera.t'"),
    "culled_for_pose_disagrees": (set_field("order.culled_for.1.world_to_camera.t", [0.0, 0.0, 9.0]),
                                  "'order.culled_for[1]' position/rotation"),
    "colour_from_nan": (set_field("order.colour_from", [0.0, float("nan"), 0.0]), "'order.colour_from'"),
    "colour_from_inf": (set_field("order.colour_from", [float("-inf"), 0.0, 0.0]), "'order.colour_from'"),
    "colour_from_huge": (set_field("order.colour_from", [0.0, 0.0, 1e301]), "'order.colour_from' is beyond"),
    "colour_from_two": (set_field("order.colour_from", [0.0, 1.0]), "'order.colour_from'"),
    "colour_from_string": (set_field("order.colour_from", "midpoint"), "'order.colour_from'"),
    "colour_from_bool": (set_field("order.colour_from", [True, 0.0, 0.0]), "'order.colour_from'"),
}


def write_malformed(tmp_path, case):
    return write_case(tmp_path / "shot.json", MALFORMED_ORDER[case][0], headset_sidecar)


@pytest.mark.parametrize("case", sorted(MALFORMED_ORDER))
def test_a_bad_order_entry_is_one_line(tmp_path, case):
    path = write_malformed(tmp_path, case)
    assert_user_error(lambda: load_sidecar(path), path, MALFORMED_ORDER[case][1])


def test_the_valid_sidecar_behind_the_cases_loads(tmp_path):
    """The cases' base file loads: each case fails by its own change alone."""
    assert load_sidecar(write_case(tmp_path / "shot.json", lambda data: None, headset_sidecar)).viewpoint is not None


@pytest.mark.parametrize("case", ["culled_for_R_scaled", "colour_from_nan", "order_unknown_key"])
def test_a_bad_order_entry_through_render(capsys, tmp_path, case):
    path = write_malformed(tmp_path, case)
    before = listing(tmp_path)
    code, out, err = run_cli(capsys, "render", "--sidecar", path, "--out", tmp_path / "out.png")
    assert MALFORMED_ORDER[case][1] in assert_one_line_error(code, err) and out == ""
    assert listing(tmp_path) == before


def test_render_reference_draws_a_recorded_order_as_gl_does(capsys, tmp_path):
    """The float64 reference of a headset eye: the same order (sorted from the viewpoint,
    culled for its cameras) and the colour seen from its origin, so it matches the GL
    render tightly; without the origin (the eye's own centre) it visibly does not."""
    path = write_json(tmp_path / "shot.json", headset_sidecar())
    for name, extra in (("ref.npy", ("--reference",)), ("gl.npy", ())):
        code, _, err = run_cli(capsys, "render", "--sidecar", path, *extra, "--out", tmp_path / name)
        assert code == 0, err
    reference, image = np.load(tmp_path / "ref.npy"), np.load(tmp_path / "gl.npy")
    assert_matches(image, reference)
    no_origin = write_json(tmp_path / "no-origin.json", headset_sidecar(viewpoint=dataclasses.replace(
        HEADSET, color_origin=None)))
    code, _, err = run_cli(capsys, "render", "--sidecar", no_origin, "--reference", "--out", tmp_path / "ref2.npy")
    assert code == 0, err
    assert_differs(image, np.load(tmp_path / "ref2.npy"))


# --------------------------------------------------------------------------- rendering


def direct(renderer, viewpoint: OrderViewpoint | None):
    """The eye as the headset draws it, straight through GLRenderer: the order sorted
    from the viewpoint's camera, culled for its cameras, coloured from its origin (None:
    the eye's own order and colour). In the renderer's context: the CLI makes its own."""
    with renderer.ctx, DepthSorter(renderer.scene) as sorter:
        if viewpoint is None:
            return renderer.render(EYE, SETTINGS, exact_order(sorter, EYE, SETTINGS))
        order = exact_order(sorter, viewpoint.camera, SETTINGS, cull_cameras=viewpoint.cull_cameras)
        return renderer.render(EYE, SETTINGS, order, color_origin=viewpoint.color_origin)


def far_apart(a, b, at_least=0.05):
    return np.abs(a.astype(np.float64) - b).max() > at_least


@pytest.mark.parametrize("viewpoint", [HEADSET, OrderViewpoint(SORT)], ids=["headset", "sort-camera-only"])
def test_render_sidecar_draws_the_recorded_order(capsys, tmp_path, demo_renderer, viewpoint):
    expected = direct(demo_renderer, viewpoint)
    assert expected[..., 3].max() > 0.5 and expected.std() > 0.05  # shows the scene
    png, js = save_screenshot(expected, headset_sidecar(viewpoint), path=tmp_path / "shot-left.png")
    code, stdout, err = run_cli(capsys, "render", "--sidecar", js, "--out", tmp_path / "again.npy")
    assert code == 0 and err == "", err
    assert "64x48" in stdout
    np.testing.assert_array_equal(np.load(tmp_path / "again.npy"), expected)  # every float bit
    code, _, err = run_cli(capsys, "render", "--sidecar", js, "--out", tmp_path / "again.png")
    assert code == 0, err
    assert (tmp_path / "again.png").read_bytes() == png.read_bytes() == encode_image(expected, ".png")

    # Negative control: the same sidecar without its "order" is the eye's own order and
    # colour, another picture; a reader that ignored the entry would draw it.
    data = json.loads(js.read_text())
    del data["order"]
    data["version"] = 1
    plain = write_json(tmp_path / "plain.json", data)
    code, _, err = run_cli(capsys, "render", "--sidecar", plain, "--out", tmp_path / "plain.npy")
    assert code == 0, err
    without = np.load(tmp_path / "plain.npy")
    np.testing.assert_array_equal(without, direct(demo_renderer, None))
    assert far_apart(without, expected)


def test_each_field_of_the_viewpoint_changes_the_picture(demo_renderer):
    """The negative controls behind the render test: the recorded order matches only
    where all three fields are honoured (the sort camera alone, its own cull, or the
    eye's colour origin each draw another picture)."""
    expected = direct(demo_renderer, HEADSET)
    for partial in (OrderViewpoint(SORT, HEADSET.cull_cameras, None), OrderViewpoint(SORT, None, ORIGIN),
                    OrderViewpoint(EYE, HEADSET.cull_cameras, ORIGIN)):
        assert far_apart(direct(demo_renderer, partial), expected), partial


def test_tiles_share_the_order_and_the_colour_origin(demo_renderer):
    """render_tiled with a colour origin: every tile evaluates the colour from it, so the
    tiles make up the one render of the eye (up to the rasterizer's rounding between
    tile projections, as for any tiled screenshot), not the eye's own colours."""
    expected = direct(demo_renderer, HEADSET)
    with demo_renderer.ctx, DepthSorter(demo_renderer.scene) as sorter:
        order = exact_order(sorter, SORT, SETTINGS, cull_cameras=HEADSET.cull_cameras)
        tiled = render_tiled(demo_renderer, sorter, order, EYE, SETTINGS, tile=16, color_origin=ORIGIN)
        own_colour = render_tiled(demo_renderer, sorter, order, EYE, SETTINGS, tile=16)
    tolerances = {"max_error": 2 * SETTINGS.p_min, "pixel_fraction": 0.002, "p999": 1e-4}
    assert_matches(tiled, expected, **tolerances)
    assert_differs(own_colour, expected, **tolerances)
    assert_differs(tiled, own_colour, **tolerances)


def test_a_viewpoint_entry_is_plain_json():
    entry = viewpoint_entry(HEADSET)
    assert json.loads(json.dumps(entry, allow_nan=False)) == copy.deepcopy(entry)
    assert entry["colour_from"] == ORIGIN.tolist() and entry["culled_for"][1]["world_to_camera"]["t"] == \
        OTHER_EYE.t.tolist()
