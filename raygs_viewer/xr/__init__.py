"""OpenXR: the scene in a headset (docs/xr.md)."""
