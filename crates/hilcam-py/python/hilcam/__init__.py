"""hilcam from Python: scenes, cameras, the renderer with its sensor model, ground truth.

    import hilcam
    r = hilcam.Renderer(hilcam.Scene.load("scenes/satellite.toml"), hilcam.Camera.preset("nav1024"), spp=2, seed=1)
    f = r.render([0, 0, 22])          # f.radiance (H x W float32), f.dn (uint16)
    t = r.truth([0, 0, 22])           # depth, mask, normal, body_xyz, footprint

The reference is docs/python.md; `hilcam.dataset` renders pose lists to images + labels.
"""

from ._hilcam import (  # noqa: F401
    Camera,
    Frame,
    HilcamError,
    Planet,
    Renderer,
    Scene,
    __version__,
    camera_presets,
)

__all__ = ["Camera", "Frame", "HilcamError", "Planet", "Renderer", "Scene", "camera_presets", "__version__"]
