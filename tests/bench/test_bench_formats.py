"""``bench formats``: every target written, read back and compared; the report's rows."""

from __future__ import annotations

from raygs_viewer.bench import formats


def test_the_demo_through_every_format(gl_ctx, capsys):
    options = formats.FormatsOptions(("demo",), samples=False, width=32, repeat=1, command_line="bench formats")
    results = formats.run_formats(options, gl_ctx)
    (name, _, rows), = results.scenes
    assert name == "demo" and [row.format for row in rows] == ["INRIA PLY", ".splat", "spz v3", "spz v4"]
    ply, splat, spz3, spz4 = rows
    assert all(row.count == 3914 and row.size > 0 for row in rows)
    # PLY keeps everything to float32 rounding; .splat loses the SH rest; .spz quantises.
    assert ply.errors.scale_relative < 1e-5 and ply.errors.rotation_degrees < 1e-3 and ply.psnr > 60
    assert splat.errors.sh_degree_lost and splat.psnr < ply.psnr
    assert 0 < spz3.errors.opacity_max <= 0.5 / 255 + 1e-6 and spz3.errors == spz4.errors
    assert spz4.size < spz3.size < ply.size
    report = formats.format_report(results)
    assert report.count("| spz v") == 2 and "| .splat |" in report and "lost" in report
