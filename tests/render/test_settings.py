"""RenderSettings' own checks, and the one list of the accuracy options."""

import math
from dataclasses import dataclass, fields, replace
from pathlib import Path

import pytest

from raygs_viewer.cli.argtypes import Parser
from raygs_viewer.cli.commands import describe_accuracy
from raygs_viewer.cli.options import add_settings_options, option_flag, render_settings
from raygs_viewer.errors import UserError
from raygs_viewer.render.setting_info import Setting, Shown, setting, settings_table
from raygs_viewer.render.settings import ACCURACY_FIELDS, ACCURACY_PRESETS, RenderSettings, apply_preset
from raygs_viewer.viewer.overlay import describe_settings

SWITCHES = ("mip", "mip_modulation", "gs_compensation", "alpha_clamp", "transmittance_cutoff")


@pytest.mark.parametrize("switch", SWITCHES)
@pytest.mark.parametrize("value", [1, 0, "yes", None])
def test_every_switch_takes_only_true_or_false(switch, value):
    with pytest.raises(UserError, match=f"{switch} must be true or false"):
        RenderSettings(**{switch: value})


def test_the_accuracy_fields_are_every_field_but_p_min_background_sh_degree_and_the_level_of_detail():
    assert set(ACCURACY_FIELDS) == {f.name for f in fields(RenderSettings)} - {
        "p_min", "background", "sh_degree", "lod", "lod_budget", "lod_distance"}
    assert set(SWITCHES) < set(ACCURACY_FIELDS)


@pytest.mark.parametrize("name", list(ACCURACY_PRESETS))
def test_a_preset_resets_every_accuracy_option_it_does_not_name(name):
    edited = RenderSettings(p_min=0.02, background=(0.1, 0.2, 0.3), sh_degree=1, mode="raygs-exact-mip",
                            mip=True, mip_sigma2=0.5, mip_modulation=False, gs_compensation=True, supersample=3,
                            alpha_clamp=True, transmittance_cutoff=True)
    preset = apply_preset(edited, name)
    expected = replace(RenderSettings(p_min=0.02, background=(0.1, 0.2, 0.3), sh_degree=1), **ACCURACY_PRESETS[name])
    assert preset == expected


# --------------------------------------------------------------------------- the describers

#: (settings, the split view's label, verify's line): today's strings, pinned so that
#: deriving the describers from the settings' table changes none of them.
DESCRIPTIONS = [
    ({}, "RayGS",
     "mode raygs, MIP off, supersample 1x1, alpha clamp off, transmittance cut-off off, order depth, blend float32"),
    ({"mode": "gs"}, "GS (EWA)",
     "mode gs, compensation off, supersample 1x1, alpha clamp off, transmittance cut-off off, order depth, blend float32"),
    ({"mode": "gs", "gs_compensation": True}, "GS (EWA) + comp.",
     "mode gs, compensation on, supersample 1x1, alpha clamp off, transmittance cut-off off, order depth, blend float32"),
    ({"mode": "gs", "mip": True, "mip_modulation": False}, "GS (EWA)",
     "mode gs, compensation off, supersample 1x1, alpha clamp off, transmittance cut-off off, order depth, blend float32"),
    ({"mode": "raygs-exact-mip"}, "RayGS exact MIP + MIP 0.1 px²",
     "mode raygs-exact-mip, sigma^2 0.1 px^2, modulation on, supersample 1x1, alpha clamp off, "
     "transmittance cut-off off, order depth, blend float32"),
    ({"mode": "raygs-exact-mip", "mip_sigma2": 0.37, "mip_modulation": False}, "RayGS exact MIP + MIP 0.37 px² no mod.",
     "mode raygs-exact-mip, sigma^2 0.37 px^2, modulation off, supersample 1x1, alpha clamp off, "
     "transmittance cut-off off, order depth, blend float32"),
    ({"mip": True}, "RayGS + MIP 0.1 px²",
     "mode raygs, MIP on, sigma^2 0.1 px^2, modulation on, supersample 1x1, alpha clamp off, "
     "transmittance cut-off off, order depth, blend float32"),
    ({"mip": True, "mip_modulation": False, "mip_sigma2": 0.25}, "RayGS + MIP 0.25 px² no mod.",
     "mode raygs, MIP on, sigma^2 0.25 px^2, modulation off, supersample 1x1, alpha clamp off, "
     "transmittance cut-off off, order depth, blend float32"),
    ({"mip_modulation": False, "mip_sigma2": 2.0}, "RayGS",
     "mode raygs, MIP off, supersample 1x1, alpha clamp off, transmittance cut-off off, order depth, blend float32"),
    ({"gs_compensation": True}, "RayGS",
     "mode raygs, MIP off, supersample 1x1, alpha clamp off, transmittance cut-off off, order depth, blend float32"),
    ({"supersample": 2}, "RayGS + 2×2",
     "mode raygs, MIP off, supersample 2x2, alpha clamp off, transmittance cut-off off, order depth, blend float32"),
    ({"supersample": 4, "alpha_clamp": True}, "RayGS + 4×4, alpha clamp",
     "mode raygs, MIP off, supersample 4x4, alpha clamp on, transmittance cut-off off, order depth, blend float32"),
    ({"transmittance_cutoff": True}, "RayGS + T cut-off",
     "mode raygs, MIP off, supersample 1x1, alpha clamp off, transmittance cut-off on, order depth, blend float32"),
    ({"mode": "gs", "gs_compensation": True, "supersample": 3, "alpha_clamp": True, "transmittance_cutoff": True},
     "GS (EWA) + comp., 3×3, alpha clamp, T cut-off",
     "mode gs, compensation on, supersample 3x3, alpha clamp on, transmittance cut-off on, order depth, blend float32"),
    ({"p_min": 0.02}, "RayGS + p_min 0.02",
     "mode raygs, MIP off, supersample 1x1, alpha clamp off, transmittance cut-off off, order depth, blend float32"),
    ({"p_min": math.exp(-4.0), "mip": True}, "RayGS + MIP 0.1 px², p_min 0.0183",
     "mode raygs, MIP on, sigma^2 0.1 px^2, modulation on, supersample 1x1, alpha clamp off, "
     "transmittance cut-off off, order depth, blend float32"),
    ({"order": "distance"}, "RayGS",
     "mode raygs, MIP off, supersample 1x1, alpha clamp off, transmittance cut-off off, order distance, blend float32"),
    ({"order": "per-pixel"}, "RayGS",
     "mode raygs, MIP off, supersample 1x1, alpha clamp off, transmittance cut-off off, order per-pixel (exact), blend float32"),
    ({"order": "per-pixel", "order_k": 4}, "RayGS",
     "mode raygs, MIP off, supersample 1x1, alpha clamp off, transmittance cut-off off, order per-pixel (K=4), blend float32"),
    ({"order": "distance", "order_k": 3}, "RayGS",
     "mode raygs, MIP off, supersample 1x1, alpha clamp off, transmittance cut-off off, order distance, blend float32"),
    ({"mode": "raygs-exact-mip", "mip_sigma2": 100.0, "supersample": 2, "alpha_clamp": True,
      "transmittance_cutoff": True, "order": "per-pixel", "order_k": 16, "p_min": 1e-3},
     "RayGS exact MIP + MIP 100 px², 2×2, alpha clamp, T cut-off, p_min 0.001",
     "mode raygs-exact-mip, sigma^2 100 px^2, modulation on, supersample 2x2, alpha clamp on, "
     "transmittance cut-off on, order per-pixel (K=16), blend float32"),
    ({"background": (0.1, 0.2, 0.3), "sh_degree": 1}, "RayGS",
     "mode raygs, MIP off, supersample 1x1, alpha clamp off, transmittance cut-off off, order depth, blend float32"),
]


@pytest.mark.parametrize("values, label, line", DESCRIPTIONS)
def test_the_describers_keep_their_words(values, label, line):
    settings = RenderSettings(**values)
    assert describe_settings(settings) == label
    assert describe_accuracy(settings) == line


@dataclass(frozen=True)
class WithExposure(RenderSettings):
    """The settings with one more field, as a later version might add it: nothing but
    its Setting says how to check, offer and describe it."""

    exposure: float = setting(1.0, Setting("scale the image's brightness by E (default 1)", "E", limits=(0.0, 8.0),
                                           line=Shown("exposure {:g}"), label=Shown("exposure x{:g}"),
                                           needs="per_pixel"))


def test_a_setting_added_later_reaches_every_describer():
    """The describers read each field's Setting: a hand-written describer would miss
    the new field. (The sidecar's reader: test_sidecar's test_settings_fields_flow_in_automatically.)"""
    settings = WithExposure(exposure=2.0, supersample=2, order="per-pixel")
    assert describe_settings(settings) == "RayGS + 2×2, exposure x2"
    assert describe_accuracy(settings) == ("mode raygs, MIP off, supersample 2x2, alpha clamp off, "
                                           "transmittance cut-off off, order per-pixel (exact), blend float32, "
                                           "exposure 2")
    # Where it does not apply (needs="per_pixel"), or at its default in the label, it is left out.
    assert describe_settings(replace(settings, order="depth")) == "RayGS + 2×2"
    assert describe_accuracy(replace(settings, order="depth")).endswith("order depth, blend float32")
    assert describe_settings(replace(settings, exposure=1.0)) == "RayGS + 2×2"
    # Its limits are checked ...
    with pytest.raises(UserError, match=r"exposure must be a number in \[0, 8\], got 9"):
        WithExposure(exposure=9)
    assert WithExposure(exposure=8).exposure == 8.0 and isinstance(WithExposure(exposure=8).exposure, float)
    # ... and the command line offers it, with those limits and its help.
    parser = Parser(prog="test")
    add_settings_options(parser, None, None, WithExposure)
    assert render_settings(parser.parse_args(["--exposure", "2", "--supersample", "2", "--order", "per-pixel"]),
                           WithExposure) == settings
    assert render_settings(parser.parse_args([]), WithExposure) == WithExposure()
    with pytest.raises(UserError, match=r"--exposure: 9 is not in \[0, 8\]"):
        parser.parse_args(["--exposure", "9"])
    assert "scale the image's brightness by E" in parser.format_help()


def test_a_field_without_its_setting_is_refused():
    """A field no describer knows about is an error, not a silent gap in all of them."""
    @dataclass(frozen=True)
    class Bare(RenderSettings):
        exposure: float = 1.0

    with pytest.raises(TypeError, match="Bare.exposure has no Setting"):
        Bare()


@pytest.mark.parametrize("name, low, high, inside", [("p_min", 0.0, 1.0, False), ("mip_sigma2", 0.0, 100.0, True),
                                                     ("supersample", 1, 4, True), ("order_k", 0, 16, True)])
def test_the_command_line_and_the_settings_take_the_same_values(name, low, high, inside):
    """One limit, read by both: the edges (closed or open) and just beyond them."""
    parser = Parser(prog="test")
    add_settings_options(parser, None, None)
    step = 1 if isinstance(low, int) else 1e-9
    extra = {"order": "per-pixel"} if name == "order_k" else {}
    for value, accepted in ((low, inside), (high, inside), (low - step, False), (high + step, False)):
        if accepted:
            assert getattr(render_settings(parser.parse_args([f"--{name.replace('_', '-')}", str(value)])),
                           name) == value
            assert getattr(RenderSettings(**{name: value}, **extra), name) == value
        else:
            with pytest.raises(UserError):
                parser.parse_args([f"--{name.replace('_', '-')}={value}"])
            with pytest.raises(UserError):
                RenderSettings(**{name: value}, **extra)


def test_the_viewer_docs_name_every_setting_and_its_option():
    """The sidecar's "settings" row and the command line's table in docs/viewer.md."""
    text = (Path(__file__).resolve().parents[2] / "docs" / "viewer.md").read_text()
    sidecar_row = next(line for line in text.splitlines() if line.startswith("| `settings` |"))
    options = text.split("## Render settings on the command line")[1].split("\n## ")[0]
    for row in settings_table(RenderSettings):
        assert f"`{row.name}`" in sidecar_row, row.name
        assert f"`{option_flag(row.name)}" in options, row.name
