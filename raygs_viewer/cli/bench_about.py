"""What each ``raygs-viewer bench`` kind is, in the words of its help: one line for
``bench --help`` and a description for ``bench KIND --help`` (cli/bench.py builds the
parsers from them)."""

from __future__ import annotations

from raygs_viewer.bench import cube, freshness, sort_timing
from raygs_viewer.bench import gpu as gpu_bench
from raygs_viewer.bench import lod as lod_bench
from raygs_viewer.bench import sort as sort_bench
from raygs_viewer.bench.common import count_label

#: The sizes of a full ``bench sort``, as its help names them.
SORT_COUNTS = ", ".join(count_label(n) for n in sort_bench.COUNTS)
#: bench KIND: its one-line help (in ``bench --help``) and its description (in ``bench KIND --help``).
ABOUT: dict[str, tuple[str, str]] = {
    "accuracy": (
        "GPU time and error against ground truth of every accuracy option",
        "For every accuracy configuration and every view class (training-like, far at 1/4 "
        "resolution, very close) of the demo and the shared real scenes: GPU time per frame "
        "(timer queries, as a ratio to plain RayGS) and the error against the ground truth "
        "(PSNR, p99, max). Writes a markdown report and a PNG plot."),
    "stereo": (
        "what the shared stereo sort and colour cost, and both eyes' time per headset preset",
        "For the demo and the shared real scenes: the error of the shared stereo images (one sort "
        "and SH colour from the eyes' midpoint) against per-eye ones, in the training-like and very "
        "close views at 1 m per unit and with the scene 1 m across, taken apart into sort and "
        "colour; and the GPU time of both eyes at every headset preset's resolution against each "
        "refresh rate's frame budget. Prints markdown tables and machine-readable lines."),
    "perf": (
        "per-stage frame times and the cost ratios (RayGS/GS, floor, specialisation, sort)",
        "Times every stage of a moving-view frame (cull, sort, upload, preprocess, draw) for "
        "generated scenes of 10k, 100k and 1M gaussians, small and large on screen, and the shared "
        "real scenes, at 1280x720 and 1920x1080; in the same frames EWA splatting, the floor pass "
        "(the same quads, constant fragment), the general shader variant and a float argsort. "
        "Prints a line per case and the ratios as 'NAME VALUE' lines."),
    "order": (
        "each order mode's time, error against the order of every ray, and popping in motion",
        "For the demo and the shared real scenes, from the training-like and very close views: "
        "every order mode (depth, distance, per-pixel with windows K and exact) timed as a ratio to "
        "the depth order, its error against the per-ray, pixel-integrated ground truth, and along a "
        "turn in place and a flight forward its error against each frame's per-ray truth and its "
        "popping (how much that error flickers between frames). Prints a table per view and "
        "machine-readable lines; --out writes the markdown report."),
    "sort": (
        "CPU cull and sort of generated scenes of 100k to 6M gaussians, and the drawn order's "
        "freshness while turning and flying",
        f"For generated scenes of {SORT_COUNTS} gaussians (made in memory), seen whole: the cull, keys, "
        f"sort and upload times with 1 worker, 2 and every core (medians, interleaved), the "
        f"speed-up over one worker and 'cull+sort@N' lines; then, with those latencies and the "
        f"projection to {sort_timing.PROJECTED_CORES} cores, a turn of "
        f"{cube.TURN_DEGREES_PER_S:g} deg/s and a flight of {cube.FLY_RADII_PER_S:g} "
        f"scene radii/s at {freshness.FPS:g} fps drawn with the order the window would hold: the "
        f"error against the up-to-date order for the depth, distance and per-pixel orders."),
    "formats": (
        "what .ply, .splat and .spz keep of a scene (per attribute and in renders), and load times",
        "Each reference scene (the demo, the shared INRIA PLYs, and the shared compressed-PLY and SOG "
        "samples) is loaded from its own file, then written as .ply, .splat, .spz v3 and v4 and read "
        "back: size, load time, the per-attribute error and the render PSNR against the scene; then "
        "the shared .spz sample against its INRIA PLY twin."),
    "lod": (
        "what a streamed SOG's level of detail costs and saves at each budget, against its finest level",
        "For each streamed SOG (lod-meta.json), in a view framing it, a closer and a farther one: its finest "
        "level drawn everywhere, then the view-dependent choice of levels at budgets of "
        + ", ".join(f"{f * 100:g} %" for f in lod_bench.FRACTIONS) + " of the finest level's gaussians (plus "
        "the environment's), side by side: gaussians drawn, CPU time of the choice and of the cull+sort, "
        "time of preprocess+draw (GPU timer, and drained), their ratios to the finest level, and the image's "
        "PSNR and largest error against the finest level's. Prints a table per view and machine-readable "
        "lines; --out writes the markdown report."),
    "gpu": (
        "a frame on the GPU: preprocess and draw times, fragments and fill rate, and each fill option's "
        "ratio to today's path",
        "For generated outdoor-like scenes of "
        + ", ".join(count_label(n) for n in gpu_bench.COUNTS) + " gaussians (SH degree 3, made in memory) and "
        "the shared real scenes, at 1920x1080 and as a " + gpu_bench.HEADSET.label + " stereo pair: the GPU "
        "timer of the preprocessing pass and of the draw, fragments rasterized and kept (samples-passed "
        "queries), fragments per second, RayGS against GS and against the floor pass, the CPU cull+sort, "
        "the VR budget of both eyes at 72/90/120 Hz, and each blend precision and draw layout as a ratio "
        "to today's path, measured side by side in the same frames. Prints a line per case and the "
        "markdown report; --out writes it."),
    "xr": (
        "a headset frame against the active OpenXR runtime, beside a mono frame of one eye in the same run",
        "Against the active OpenXR runtime (docs/xr.md): headset frames of SCENE (default: the demo) drawn as the "
        "window draws them (the runtime's wait, the eyes located, one sort from their midpoint, both eyes into "
        "the swapchain images, submitted; with depth too where the runtime takes it), interleaved with a mono "
        "frame of the left eye's camera and size drawn offscreen with one sort. Prints the ratio headset/mono "
        "(goal: at most 2.1), the headset frame's work outside xrWaitFrame (its wall time includes the runtime's "
        "wait), each eye's GPU time and the runtime's display period, as 'xr KIND KEY VALUE' lines and a markdown "
        "report; --out writes it. Needs pip install 'raygs-viewer[xr]' and an active runtime (exit status 2 "
        "without)."),
}
