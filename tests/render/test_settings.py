"""RenderSettings' own checks, and the one list of the accuracy options."""

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
