"""Off-screen rendering of OCCT shapes with VTK (no display needed; EGL or OSMesa).

Public API (VTK and OCP are imported only when a function runs)::

    from carbody.render import render_shape, render_views, save_png, Scene, Look, tessellate
    img = render_shape(body, "front 30°", elevation_deg=10, size=(512, 384))   # (h, w, 3) uint8
    render_views(body, "views.png")                    # front 30°, side, rear 30° side by side
    scene = Scene(tessellate(body), size=(128, 128))   # tessellate once, render many views
    img = scene.render(135, 20, look=Look(paint=(0.8, 0.1, 0.1), background=texture))

The camera follows SPEC "Frames and units" (:mod:`carbody.camera`): θ = 0 front,
90 left side (x > 0), 180 rear, 270 right side; φ elevation; orthographic unless a perspective
``distance`` is given. Faces named after a glass region (windshield, rear_window, side_window)
are glass, the rest paint.
"""
from carbody.render.mesh import GLASS_REGIONS, FaceMesh, is_glass, mirrored, named_faces, tessellate
from carbody.render.scene import Environment, Look, Scene, as_rgb, render_shape, render_views, save_png

__all__ = [
    "GLASS_REGIONS", "Environment", "FaceMesh", "Look", "Scene", "as_rgb", "is_glass", "mirrored",
    "named_faces", "render_shape", "render_views", "save_png",
    "tessellate",
]
