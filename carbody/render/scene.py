"""Off-screen VTK rendering of triangle meshes under the SPEC camera contract.

A :class:`Scene` holds the meshes of one shape on the GPU-side once; each :meth:`Scene.render`
only moves the camera and changes colours and lights, so rendering many views of one body is
cheap (a few ms at 128 px). :func:`render_shape` is the one-call version.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from carbody.errors import RenderError
from carbody.camera import View, parse_view, view_rotation
from carbody.render.mesh import FaceMesh, is_glass, tessellate

RGB = tuple[float, float, float]

#: Default colours, RGB in [0, 1].
PAINT: RGB = (0.62, 0.64, 0.68)
GLASS: RGB = (0.07, 0.09, 0.11)


def as_rgb(colour: Any) -> RGB:
    """RGB in [0, 1] from (r, g, b) floats in [0, 1], ints in [0, 255] or ``"#rrggbb"``.

    Raises:
        RenderError: anything else.
    """
    try:
        if isinstance(colour, str):
            h = colour.lstrip("#")
            if len(h) != 6:
                raise ValueError
            return tuple(int(h[i:i + 2], 16) / 255.0 for i in (0, 2, 4))  # type: ignore[return-value]
        c = np.asarray(colour, dtype=float).reshape(-1)
        if c.shape != (3,) or not np.all(np.isfinite(c)) or c.min() < 0:
            raise ValueError
        if c.max() > 1.0:          # 0-255 convention
            c = c / 255.0
        if c.max() > 1.0:
            raise ValueError
        return tuple(float(v) for v in c)  # type: ignore[return-value]
    except (ValueError, TypeError):
        raise RenderError(f"not a colour: {colour!r} (use (r, g, b) in 0-1, 0-255 or '#rrggbb')") from None


@dataclass
class Look:
    """Materials, lights and background of a render.

    Attributes:
        paint: body colour, RGB in [0, 1].
        glass: glass colour (windshield, rear window, side windows).
        colours: {face name: RGB} overriding paint/glass for those names.
        background: RGB colour, or an (h, w, 3) uint8 picture (resized to the render size).
        light_azimuth_deg, light_elevation_deg: key light direction relative to the camera
            (0, 0 = from the camera; positive azimuth = from the image's right).
        light_intensity: key light intensity (a fill light from the camera adds 0.35).
        ambient, diffuse, specular: paint material coefficients (glass is more specular).
    """

    paint: RGB = PAINT
    glass: RGB = GLASS
    colours: dict[str, RGB] = field(default_factory=dict)
    background: Any = (1.0, 1.0, 1.0)
    light_azimuth_deg: float = 30.0
    light_elevation_deg: float = 40.0
    light_intensity: float = 0.9
    ambient: float = 0.2
    diffuse: float = 0.8
    specular: float = 0.35
    environment: "Environment | None" = None

    def colour_of(self, name: str) -> RGB:
        if name in self.colours:
            return as_rgb(self.colours[name])
        return as_rgb(self.glass) if is_glass(name) else as_rgb(self.paint)


@dataclass
class Environment:
    """An outdoor light around the car, shaded per vertex on the CPU (paint and glass only):
    a sky above the horizon and a darker ground below, seen in the clear coat and the glass by
    reflection (Schlick's Fresnel: strongest at grazing angles, so a car's flanks mirror the
    horizon as a photo shows), a sun for diffuse light and its highlight, sky light from above.

    Attributes:
        sky, ground: RGB of the sky (overhead) and of the ground, as reflected.
        horizon_sharpness: how sharply the reflected horizon cuts (larger = sharper).
        sun_azimuth_deg, sun_elevation_deg: sun direction in the car frame (θ convention).
        sun: sun intensity; sky_light: the sky's diffuse light from above.
        paint_reflectance, glass_reflectance: reflectance at normal incidence (Fresnel's F0 × gain).
        interior: RGB seen through the glass (a dark cabin).
    """

    sky: RGB = (0.75, 0.82, 0.92)
    ground: RGB = (0.22, 0.21, 0.2)
    horizon_sharpness: float = 12.0
    sun_azimuth_deg: float = 40.0
    sun_elevation_deg: float = 45.0
    sun: float = 0.75
    sky_light: float = 0.45
    paint_reflectance: float = 0.12
    glass_reflectance: float = 0.3
    interior: RGB = (0.04, 0.04, 0.045)


def environment_shading(points: np.ndarray, normals: np.ndarray, camera: np.ndarray, base: np.ndarray,
                        env: Environment, glass: bool, specular: float) -> np.ndarray:
    """(n, 3) float RGB in [0, 1] of vertices (n, 3) with unit normals (n, 3) seen from
    ``camera`` (3,) under ``env``; ``base`` is the paint colour (or the glass's tint)."""
    v = camera[None, :] - points
    v /= np.linalg.norm(v, axis=1, keepdims=True) + 1e-12
    n = normals * np.where((normals * v).sum(1, keepdims=True) < 0, -1.0, 1.0)   # two-sided
    ndv = np.clip((n * v).sum(1, keepdims=True), 0, 1)
    r = 2 * ndv * n - v
    t = 1 / (1 + np.exp(-env.horizon_sharpness * r[:, 2:3]))             # 0 ground .. 1 sky
    sky = np.asarray(env.sky, dtype=float)
    reflected = (1 - t) * np.asarray(env.ground) + t * sky * (0.75 + 0.25 * np.clip(r[:, 2:3], 0, 1))
    fresnel = 1 - ndv
    fresnel = fresnel ** 5
    az, el = np.radians([env.sun_azimuth_deg, env.sun_elevation_deg])
    sun = np.array([np.sin(az) * np.cos(el), -np.cos(az) * np.cos(el), np.sin(el)])
    diffuse = np.clip(n @ sun, 0, 1)[:, None]
    highlight = np.clip(r @ sun, 0, 1)[:, None] ** 40 * specular
    if glass:
        k = env.glass_reflectance + (1 - env.glass_reflectance) * fresnel
        out = (1 - k) * (np.asarray(env.interior) + 0.3 * np.asarray(base)) + k * reflected + 1.5 * highlight
    else:
        k = env.paint_reflectance + (1 - env.paint_reflectance) * fresnel * 0.8
        light = env.sky_light * (0.75 + 0.25 * n[:, 2:3]) + env.sun * diffuse
        out = (1 - k) * np.asarray(base) * light + k * reflected + highlight
    return np.clip(out, 0, 1)


def _quiet_vtk() -> None:
    from vtkmodules.vtkCommonCore import vtkLogger, vtkObject

    vtkObject.GlobalWarningDisplayOff()
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_OFF)


def _polydata(meshes: Sequence[FaceMesh]):
    """One vtkPolyData (with point normals) of several meshes."""
    from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData
    from vtkmodules.vtkFiltersCore import vtkPolyDataNormals

    verts, tris, base = [], [], 0
    for m in meshes:
        verts.append(m.vertices)
        tris.append(m.triangles + base)
        base += len(m.vertices)
    v = np.ascontiguousarray(np.concatenate(verts), dtype=np.float64)
    t = np.concatenate(tris).astype(np.int64)
    pts = vtkPoints()
    pts.SetData(numpy_to_vtk(v, deep=True))
    cells = vtkCellArray()
    offsets = np.arange(0, 3 * len(t) + 1, 3, dtype=np.int64)
    cells.SetData(numpy_to_vtkIdTypeArray(offsets, deep=True),
                  numpy_to_vtkIdTypeArray(np.ascontiguousarray(t.ravel()), deep=True))
    poly = vtkPolyData()
    poly.SetPoints(pts)
    poly.SetPolys(cells)
    normals = vtkPolyDataNormals()
    normals.SetInputData(poly)
    normals.SplittingOff()
    normals.ConsistencyOff()
    normals.AutoOrientNormalsOff()
    normals.ComputePointNormalsOn()
    normals.Update()
    out = vtkPolyData()
    out.DeepCopy(normals.GetOutput())
    return out


def _mesa_cache_or_none() -> None:
    """Mesa (VTK's off-screen renderer) keeps compiled shaders under ``$XDG_CACHE_HOME`` or
    ``~/.cache`` and says so on stderr, twice, when it cannot: under a home that cannot be
    written its cache is turned off instead (it saves milliseconds a render)."""
    import os

    if "MESA_SHADER_CACHE_DIR" in os.environ or "MESA_SHADER_CACHE_DISABLE" in os.environ:
        return
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    try:
        os.makedirs(base, exist_ok=True)
        writable = os.access(base, os.W_OK)
    except OSError:
        writable = False
    if not writable:
        os.environ["MESA_SHADER_CACHE_DISABLE"] = "true"


class Scene:
    """Meshes ready to render from any view.

    Args:
        meshes: :class:`~carbody.render.mesh.FaceMesh` list (e.g. from
            :func:`~carbody.render.mesh.tessellate`); faces with the same name share a material.
        size: (width, height) of the output image, pixels.
        antialias: render at this multiple of ``size`` and average down (1 = off).
    """

    def __init__(self, meshes: Sequence[FaceMesh], size: tuple[int, int] = (512, 384), antialias: int = 2):
        from vtkmodules.vtkRenderingCore import (vtkActor, vtkPolyDataMapper, vtkRenderer,
                                                 vtkRenderWindow, vtkWindowToImageFilter)
        import vtkmodules.vtkRenderingOpenGL2  # noqa: F401  (registers the OpenGL/EGL backend)

        _quiet_vtk()
        if not meshes:
            raise RenderError("nothing to render: no meshes")
        w, h = (int(size[0]), int(size[1]))
        if w < 4 or h < 4 or w > 8192 or h > 8192:
            raise RenderError(f"render size must be 4..8192 px each way, got {size}")
        self.size = (w, h)
        self.antialias = max(1, int(antialias))
        allv = np.concatenate([m.vertices for m in meshes])
        step = max(1, len(allv) // 20000)
        self._points = allv[::step]
        self._points = np.vstack([self._points, allv.min(0), allv.max(0)])
        self.radius = float(np.linalg.norm(allv.max(0) - allv.min(0)) / 2) or 1.0

        self._renderer = vtkRenderer()
        self._renderer.SetTwoSidedLighting(True)
        self._renderer.SetAutomaticLightCreation(False)
        _mesa_cache_or_none()
        self._window = vtkRenderWindow()
        self._window.SetOffScreenRendering(1)
        self._window.SetAlphaBitPlanes(1)
        self._window.SetMultiSamples(0)
        self._window.AddRenderer(self._renderer)
        self._window.SetSize(w * self.antialias, h * self.antialias)
        self._renderer.SetBackground(0.0, 0.0, 0.0)
        self._renderer.SetBackgroundAlpha(0.0)

        self._actors: dict[str, Any] = {}
        self._polys: dict[str, Any] = {}
        self._shading: dict[str, tuple] = {}
        groups: dict[str, list[FaceMesh]] = {}
        for m in meshes:
            groups.setdefault(m.name, []).append(m)
        for name, ms in groups.items():
            mapper = vtkPolyDataMapper()
            poly = _polydata(ms)
            mapper.SetInputData(poly)
            mapper.ScalarVisibilityOff()
            self._polys[name] = poly
            actor = vtkActor()
            actor.SetMapper(mapper)
            self._renderer.AddActor(actor)
            self._actors[name] = actor
        self._grab = vtkWindowToImageFilter()
        self._grab.SetInput(self._window)
        self._grab.SetInputBufferTypeToRGBA()
        self._grab.ReadFrontBufferOff()
        self._lights = None

    def _set_lights(self, look: Look) -> None:
        from vtkmodules.vtkRenderingCore import vtkLight

        if self._lights is None:
            key, fill = vtkLight(), vtkLight()
            for light in (key, fill):
                light.SetLightTypeToCameraLight()
                light.SetFocalPoint(0.0, 0.0, 0.0)
                self._renderer.AddLight(light)
            fill.SetPosition(0.0, 0.0, 1.0)
            self._lights = (key, fill)
        key, fill = self._lights
        az, el = np.radians([look.light_azimuth_deg, look.light_elevation_deg])
        key.SetPosition(np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el))
        key.SetIntensity(float(look.light_intensity))
        fill.SetIntensity(0.35)

    def _shade_environment(self, name: str, actor, look: Look) -> bool:
        """Per-vertex colours from ``look.environment`` on paint and glass actors; False when
        the actor keeps VTK's lighting (no environment, or a detail named in ``look.colours``)."""
        from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy

        mapper = actor.GetMapper()
        env = look.environment
        if env is None or name in look.colours or getattr(self, "_projection", None) is None:
            mapper.ScalarVisibilityOff()
            return False
        poly = self._polys[name]
        if name not in self._shading:
            pts = vtk_to_numpy(poly.GetPoints().GetData()).astype(float)
            nrm = vtk_to_numpy(poly.GetPointData().GetNormals()).astype(float)
            nrm /= np.linalg.norm(nrm, axis=1, keepdims=True) + 1e-12
            self._shading[name] = (pts, nrm)
        pts, nrm = self._shading[name]
        rgb = environment_shading(pts, nrm, np.asarray(self._projection[0]), np.asarray(look.colour_of(name)),
                                  env, is_glass(name), look.specular)
        arr = numpy_to_vtk(np.ascontiguousarray((rgb * 255 + 0.5).astype(np.uint8)), deep=True)
        arr.SetName("shade")
        poly.GetPointData().SetScalars(arr)
        mapper.SetColorModeToDirectScalars()
        mapper.ScalarVisibilityOn()
        poly.Modified()
        prop = actor.GetProperty()
        prop.SetAmbient(1.0)
        prop.SetDiffuse(0.0)
        prop.SetSpecular(0.0)
        prop.LightingOff()
        return True

    def _set_materials(self, look: Look) -> None:
        for name, actor in self._actors.items():
            if self._shade_environment(name, actor, look):
                continue
            actor.GetProperty().LightingOn()
            prop = actor.GetProperty()
            prop.SetColor(*look.colour_of(name))
            glass = is_glass(name) and name not in look.colours
            prop.SetAmbient(look.ambient)
            prop.SetDiffuse(0.45 if glass else look.diffuse)
            prop.SetSpecular(0.8 if glass else look.specular)
            prop.SetSpecularPower(60.0 if glass else 25.0)
            prop.SetSpecularColor(1.0, 1.0, 1.0)
            prop.SetInterpolationToPhong()

    def _set_camera(self, view_deg: float, elevation_deg: float, roll_deg: float,
                    distance: float | None, fill: float, offset: tuple[float, float]) -> None:
        if not (abs(elevation_deg) < 89.0):
            raise RenderError(f"elevation must be within ±89°, got {elevation_deg}")
        if not (0.05 <= fill <= 4.0):
            raise RenderError(f"fill must be 0.05..4, got {fill}")
        d, r, w = view_rotation(View(view_deg, elevation_deg, roll_deg))
        f = -d
        cam = self._renderer.GetActiveCamera()
        aspect = self.size[0] / self.size[1]
        lo, hi = self._points.min(0), self._points.max(0)
        centre = (lo + hi) / 2
        if distance is None:
            pos = centre + 4.0 * self.radius * d
            q = self._points - pos
            x, y = q @ r, q @ w
            mid_x, mid_y = (x.max() + x.min()) / 2, (y.max() + y.min()) / 2
            half = max((y.max() - y.min()) / 2, (x.max() - x.min()) / 2 / aspect) / fill
            half = max(half, 1e-9)
            cam.ParallelProjectionOn()
            cam.SetParallelScale(half)
            ndc = (mid_x / (half * aspect), mid_y / half)
        else:
            if not (distance > self.radius * 1.05):
                raise RenderError(f"camera distance {distance:g} is inside the shape "
                                  f"(bounding radius {self.radius:g})")
            pos = centre + float(distance) * d
            q = self._points - pos
            z = q @ f
            x, y = (q @ r) / z, (q @ w) / z
            mid_x, mid_y = (x.max() + x.min()) / 2, (y.max() + y.min()) / 2
            half = max((y.max() - y.min()) / 2, (x.max() - x.min()) / 2 / aspect) / fill
            half = max(half, 1e-9)
            cam.ParallelProjectionOff()
            cam.SetViewAngle(float(np.degrees(2 * np.arctan(half))))
            ndc = (mid_x / (half * aspect), mid_y / half)
        self._projection = (pos, r, w, f, half, aspect, distance is not None,
                            (ndc[0] - 2 * offset[0], ndc[1] + 2 * offset[1]))
        cam.SetPosition(*pos)
        cam.SetFocalPoint(*(pos + f))
        cam.SetViewUp(*w)
        # Window centre moves the projection so the shape's box is centred, then by the offset.
        cam.SetWindowCenter(*self._projection[-1])
        self._renderer.ResetCameraClippingRange()

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(min (3,), max (3,)) corners of the meshes' bounding box, model units."""
        return self._points.min(0), self._points.max(0)

    def pixel_rays(self) -> tuple[np.ndarray, np.ndarray]:
        """(camera position (3,), ray directions (h, w, 3)) through the pixel centres of the last
        render, model units; perspective only (the rays of an orthographic camera are parallel).

        Raises:
            RenderError: no render yet, or the last one was orthographic.
        """
        if getattr(self, "_projection", None) is None or not self._projection[6]:
            raise RenderError("pixel_rays() needs a perspective render() first")
        pos, r, w, f, half, aspect, _, (wx, wy) = self._projection
        W, H = self.size
        nx = (np.arange(W) + 0.5) / W * 2 - 1
        ny = 1 - (np.arange(H) + 0.5) / H * 2
        x = (nx[None, :] + wx) * half * aspect
        y = (ny[:, None] + wy) * half
        rays = f[None, None, :] + x[..., None] * r[None, None, :] + y[..., None] * w[None, None, :]
        return np.asarray(pos, dtype=float), rays

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixel positions (N, 2) = (u, v) of (N, 3) model points in the last render
        (u right, v down, pixel centres at integer + 0.5)."""
        if getattr(self, "_projection", None) is None:
            raise RenderError("project() needs a render() first")
        pos, r, w, f, half, aspect, perspective, (wx, wy) = self._projection
        q = np.asarray(points, dtype=float).reshape(-1, 3) - pos
        x, y = q @ r, q @ w
        if perspective:
            z = q @ f
            x, y = x / z, y / z
        nx, ny = x / (half * aspect) - wx, y / half - wy
        W, H = self.size
        return np.stack([(nx + 1) / 2 * W, (1 - ny) / 2 * H], axis=1)

    def render(self, view_deg: float | str = 90.0, elevation_deg: float = 0.0, roll_deg: float = 0.0,
               look: Look | None = None, distance: float | None = None, fill: float = 0.9,
               offset: tuple[float, float] = (0.0, 0.0), return_alpha: bool = False) -> np.ndarray:
        """Render one view.

        Args:
            view_deg: θ in degrees or a name (``"front 30°"``, see
                :func:`~carbody.camera.parse_view`).
            elevation_deg: φ, degrees.
            roll_deg: ρ, degrees (positive turns the content counter-clockwise).
            look: materials, lights, background (default :class:`Look`).
            distance: ``None`` for the orthographic camera of the contract; else a perspective
                camera this far (model units) from the shape's box centre along d.
            fill: the shape's projected box spans this fraction of the image's width or height
                (whichever binds).
            offset: (dx, dy) shift of the content as a fraction of the image (right, down).
            return_alpha: also return the coverage mask.

        Returns:
            (h, w, 3) uint8 RGB; with ``return_alpha`` also (h, w) float coverage in [0, 1].
        """
        from vtkmodules.util.numpy_support import vtk_to_numpy

        look = look or Look()
        self._set_camera(parse_view(view_deg), float(elevation_deg), float(roll_deg), distance,
                         float(fill), (float(offset[0]), float(offset[1])))
        self._set_lights(look)
        self._set_materials(look)
        self._window.Render()
        self._grab.Modified()
        self._grab.Update()
        img = self._grab.GetOutput()
        W, H = img.GetDimensions()[:2]
        rgba = vtk_to_numpy(img.GetPointData().GetScalars()).reshape(H, W, 4)[::-1].astype(np.float32) / 255
        a = self.antialias
        if a > 1:
            w, h = self.size
            rgba = rgba[:h * a, :w * a].reshape(h, a, w, a, 4).mean(axis=(1, 3))
        # The window stores premultiplied colour over a black, transparent background.
        alpha = rgba[..., 3:4]
        out = rgba[..., :3] + (1 - alpha) * _background(look.background, self.size)
        out = np.clip(out * 255 + 0.5, 0, 255).astype(np.uint8)
        return (out, alpha[..., 0]) if return_alpha else out


def _background(background: Any, size: tuple[int, int]) -> np.ndarray:
    """(h, w, 3) float in [0, 1] (or broadcastable (3,)) from a colour or picture."""
    if isinstance(background, np.ndarray) and background.ndim == 3:
        w, h = size
        pic = background
        if pic.shape[:2] != (h, w):
            import cv2

            pic = cv2.resize(pic, (w, h), interpolation=cv2.INTER_AREA)
        pic = pic[..., :3].astype(np.float32)
        return pic / 255.0 if background.dtype == np.uint8 or pic.max() > 1 else pic
    return np.asarray(as_rgb(background), dtype=np.float32)


def render_shape(shape_or_faces: Any, view_deg: float | str = 90.0, elevation_deg: float = 0.0,
                 roll_deg: float = 0.0, size: tuple[int, int] = (512, 384),
                 colours: dict[str, Any] | None = None, paint: Any = PAINT, glass: Any = GLASS,
                 background: Any = (1.0, 1.0, 1.0), distance: float | None = None,
                 fill: float = 0.9, antialias: int = 2, **look: Any) -> np.ndarray:
    """Render an OCCT shape (or named faces) off-screen: (h, w, 3) uint8 RGB.

    Args:
        shape_or_faces: a ``TopoDS_Shape``, cadquery/build123d object, ``carbody.surface.Body``
            or [(region name, face)] (see :func:`~carbody.render.mesh.named_faces`); faces of the
            glass regions get ``glass``, the others ``paint``, ``colours`` overrides by name.
        view_deg, elevation_deg, roll_deg: θ, φ, ρ of SPEC (degrees); θ may be a name.
        size: (width, height) pixels.
        background: RGB colour or an (h, w, 3) uint8 picture.
        distance: None = orthographic; else perspective camera distance in model units.
        fill: fraction of the image the shape spans.
        **look: further :class:`Look` fields (``light_azimuth_deg``, ``specular``, ...).

    Raises:
        RenderError: no faces, bad size, colour, view or distance.
    """
    scene = Scene(tessellate(shape_or_faces), size=size, antialias=antialias)
    lk = Look(paint=as_rgb(paint), glass=as_rgb(glass), colours=dict(colours or {}),
              background=background, **look)
    return scene.render(view_deg, elevation_deg, roll_deg, look=lk, distance=distance, fill=fill)


def render_views(shape_or_faces: Any, path: str | Path | None = None,
                 views: Sequence[float | str] = ("front 30°", "side", "rear 30°"),
                 size: tuple[int, int] = (400, 300), elevation_deg: float = 10.0,
                 **kwargs: Any) -> np.ndarray:
    """Render several views side by side (one tessellation) and optionally save them as PNG.

    Returns:
        (h, w × len(views), 3) uint8 RGB strip.
    """
    scene = Scene(tessellate(shape_or_faces), size=size, antialias=kwargs.pop("antialias", 2))
    look_fields = set(Look.__dataclass_fields__)
    lk = Look(**{k: v for k, v in kwargs.items() if k in look_fields})
    cam = {k: v for k, v in kwargs.items() if k in ("distance", "fill", "roll_deg")}
    strip = np.concatenate([scene.render(v, elevation_deg, look=lk, **cam) for v in views], axis=1)
    if path is not None:
        save_png(strip, path)
    return strip


def save_png(image: np.ndarray, path: str | Path) -> Path:
    """Write an (h, w, 3) or (h, w) uint8 image as PNG, atomically (no half-written file).

    Raises:
        RenderError: not an image array, or the file cannot be written.
    """
    import cv2

    from carbody.occ.step_curves import atomic_write

    arr = np.asarray(image)
    if arr.dtype != np.uint8 or arr.ndim not in (2, 3) or (arr.ndim == 3 and arr.shape[2] not in (3, 4)):
        raise RenderError(f"save_png needs an (h, w[, 3|4]) uint8 array, got {arr.dtype} {arr.shape}")
    path = Path(path)
    if arr.ndim == 3:
        arr = cv2.cvtColor(arr, cv2.COLOR_RGB2BGR if arr.shape[2] == 3 else cv2.COLOR_RGBA2BGRA)
    ok, data = cv2.imencode(".png", arr)  # in memory: a full disk is then Python's error, which says so
    if not ok:
        raise RenderError(f"{path}: cannot encode the picture as PNG")
    try:
        return atomic_write(path, lambda tmp: Path(tmp).write_bytes(data.tobytes()))
    except OSError as exc:
        raise RenderError(f"{path}: cannot write it ({(exc.strerror or str(exc)).lower()})") from None
