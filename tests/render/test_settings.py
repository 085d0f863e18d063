"""RenderSettings' own checks, and the one list of the accuracy options."""

import math
from dataclasses import fields, replace

import pytest

from raygs_viewer.errors import UserError
from raygs_viewer.render.settings import ACCURACY_FIELDS, ACCURACY_PRESETS, RenderSettings, apply_preset

SWITCHES = ("mip", "mip_modulation", "gs_compensation", "alpha_clamp", "transmittance_cutoff")


@pytest.mark.parametrize("switch", SWITCHES)
@pytest.mark.parametrize("value", [1, 0, "yes", None])
def test_every_switch_takes_only_true_or_false(switch, value):
    with pytest.raises(UserError, match=f"{switch} must be true or false"):
        RenderSettings(**{switch: value})


def test_the_accuracy_fields_are_every_field_but_p_min_background_and_sh_degree():
    assert set(ACCURACY_FIELDS) == {f.name for f in fields(RenderSettings)} - {"p_min", "background", "sh_degree"}
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
     "mode raygs, MIP off, supersample 1x1, alpha clamp off, transmittance cut-off off, order depth"),
    ({"mode": "gs"}, "GS (EWA)",
     "mode gs, compensation off, supersample 1x1, alpha clamp off, transmittance cut-off off, order depth"),
    ({"mode": "gs", "gs_compensation": True}, "GS (EWA) + comp.",
     "mode gs, compensation on, supersample 1x1, alpha clamp off, transmittance cut-off off, order depth"),
    ({"mode": "gs", "mip": True, "mip_modulation": False}, "GS (EWA)",
     "mode gs, compensation off, supersample 1x1, alpha clamp off, transmittance cut-off off, order depth"),
    ({"mode": "raygs-exact-mip"}, "RayGS exact MIP + MIP 0.1 px²",
     "mode raygs-exact-mip, sigma^2 0.1 px^2, modulation on, supersample 1x1, alpha clamp off, "
     "transmittance cut-off off, order depth"),
    ({"mode": "raygs-exact-mip", "mip_sigma2": 0.37, "mip_modulation": False}, "RayGS exact MIP + MIP 0.37 px² no mod.",
     "mode raygs-exact-mip, sigma^2 0.37 px^2, modulation off, supersample 1x1, alpha clamp off, "
     "transmittance cut-off off, order depth"),
    ({"mip": True}, "RayGS + MIP 0.1 px²",
     "mode raygs, MIP on, sigma^2 0.1 px^2, modulation on, supersample 1x1, alpha clamp off, "
     "transmittance cut-off off, order depth"),
    ({"mip": True, "mip_modulation": False, "mip_sigma2": 0.25}, "RayGS + MIP 0.25 px² no mod.",
     "mode raygs, MIP on, sigma^2 0.25 px^2, modulation off, supersample 1x1, alpha clamp off, "
     "transmittance cut-off off, order depth"),
    ({"mip_modulation": False, "mip_sigma2": 2.0}, "RayGS",
     "mode raygs, MIP off, supersample 1x1, alpha clamp off, transmittance cut-off off, order depth"),
    ({"gs_compensation": True}, "RayGS",
     "mode raygs, MIP off, supersample 1x1, alpha clamp off, transmittance cut-off off, order depth"),
    ({"supersample": 2}, "RayGS + 2×2",
     "mode raygs, MIP off, supersample 2x2, alpha clamp off, transmittance cut-off off, order depth"),
    ({"supersample": 4, "alpha_clamp": True}, "RayGS + 4×4, alpha clamp",
     "mode raygs, MIP off, supersample 4x4, alpha clamp on, transmittance cut-off off, order depth"),
    ({"transmittance_cutoff": True}, "RayGS + T cut-off",
     "mode raygs, MIP off, supersample 1x1, alpha clamp off, transmittance cut-off on, order depth"),
    ({"mode": "gs", "gs_compensation": True, "supersample": 3, "alpha_clamp": True, "transmittance_cutoff": True},
     "GS (EWA) + comp., 3×3, alpha clamp, T cut-off",
     "mode gs, compensation on, supersample 3x3, alpha clamp on, transmittance cut-off on, order depth"),
    ({"p_min": 0.02}, "RayGS + p_min 0.02",
     "mode raygs, MIP off, supersample 1x1, alpha clamp off, transmittance cut-off off, order depth"),
    ({"p_min": math.exp(-4.0), "mip": True}, "RayGS + MIP 0.1 px², p_min 0.0183",
     "mode raygs, MIP on, sigma^2 0.1 px^2, modulation on, supersample 1x1, alpha clamp off, "
     "transmittance cut-off off, order depth"),
    ({"order": "distance"}, "RayGS",
     "mode raygs, MIP off, supersample 1x1, alpha clamp off, transmittance cut-off off, order distance"),
    ({"order": "per-pixel"}, "RayGS",
     "mode raygs, MIP off, supersample 1x1, alpha clamp off, transmittance cut-off off, order per-pixel (exact)"),
    ({"order": "per-pixel", "order_k": 4}, "RayGS",
     "mode raygs, MIP off, supersample 1x1, alpha clamp off, transmittance cut-off off, order per-pixel (K=4)"),
    ({"order": "distance", "order_k": 3}, "RayGS",
     "mode raygs, MIP off, supersample 1x1, alpha clamp off, transmittance cut-off off, order distance"),
    ({"mode": "raygs-exact-mip", "mip_sigma2": 100.0, "supersample": 2, "alpha_clamp": True,
      "transmittance_cutoff": True, "order": "per-pixel", "order_k": 16, "p_min": 1e-3},
     "RayGS exact MIP + MIP 100 px², 2×2, alpha clamp, T cut-off, p_min 0.001",
     "mode raygs-exact-mip, sigma^2 100 px^2, modulation on, supersample 2x2, alpha clamp on, "
     "transmittance cut-off on, order per-pixel (K=16)"),
    ({"background": (0.1, 0.2, 0.3), "sh_degree": 1}, "RayGS",
     "mode raygs, MIP off, supersample 1x1, alpha clamp off, transmittance cut-off off, order depth"),
]


@pytest.mark.parametrize("values, label, line", DESCRIPTIONS)
def test_the_describers_keep_their_words(values, label, line):
    from raygs_viewer.cli.commands import describe_accuracy
    from raygs_viewer.viewer.overlay import describe_settings

    settings = RenderSettings(**values)
    assert describe_settings(settings) == label
    assert describe_accuracy(settings) == line
