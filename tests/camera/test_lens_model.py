"""The stereo preview's lens model (camera/lens_model): its bounds. The warp itself,
float64 reference and GL pass side by side, is tested in tests/render/test_stereo_frame_passes.py."""

import pytest

from raygs_viewer.camera.lens_model import LensModel
from raygs_viewer.errors import UserError


@pytest.mark.parametrize("field, value", [
    ("k1", -0.1), ("k1", 10.5), ("k2", float("nan")), ("k2", float("inf")), ("chroma_red", 0.4),
    ("chroma_blue", 2.5), ("k1", True), ("chroma_red", "1.0"),
])
def test_bad_lens_values_are_user_errors(field, value):
    with pytest.raises(UserError) as info:
        LensModel(**{field: value})
    message = str(info.value)
    assert "\n" not in message and field.replace("_", " ") in message and repr(value) in message


def test_lens_values_at_the_bounds_are_accepted():
    model = LensModel(k1=0, k2=10, chroma_red=0.5, chroma_blue=2)
    assert (model.k1, model.k2, model.chroma_red, model.chroma_blue) == (0.0, 10.0, 0.5, 2.0)
    assert isinstance(model.k1, float)
