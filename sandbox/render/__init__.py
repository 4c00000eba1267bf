"""Drawing: Taichi kernels that splat particles into an image field (raster.py), colour maps (colormaps.py), and
writers for PNG, GIF and MP4 (video.py). Rendering only reads simulation state."""
