"""raygs-viewer: ray-based Gaussian splatting on a hardware rasterizer."""

__version__ = "0.1.0"
