"""Where the GLSL sources are found: in the installed package, and in a source checkout
(where ``raygs_viewer`` is imported from the working tree and ``raygs_viewer.glsl``
does not exist as a package)."""

from pathlib import Path

from raygs_viewer.render.gl.shaders import CHECKOUT_GLSL, shader_source

REPO_GLSL = Path(__file__).resolve().parents[2] / "glsl"


def test_a_checkout_reads_glsl_beside_the_package():
    assert CHECKOUT_GLSL == REPO_GLSL
    assert (CHECKOUT_GLSL / "preprocess.comp").is_file()


def test_every_stage_file_loads_with_its_includes_expanded():
    for path in sorted(REPO_GLSL.iterdir()):
        if path.suffix in (".vert", ".frag", ".comp"):
            source = shader_source(path.name)
            assert "#include" not in source and source.lstrip().startswith("#version"), path.name
