"""Nimbus, a production volumetric path tracer, from Python.

Load a scene (glTF, OBJ, USD; OpenVDB volumes), render it to NumPy arrays, write EXR and PNG files::

    import nimbus
    scene = nimbus.load("assets/cloud.gltf")
    image = nimbus.render(scene, spp=16, width=320, seed=1)
    beauty = image.layers["beauty"]          # float32, height x width x 4 (R, G, B, A)
    image.write("cloud.exr"); image.to_png("cloud.png", exposure=0)

Renders release the GIL and run on worker threads of their own; Ctrl-C (KeyboardInterrupt) cancels one within
a fraction of a second. Every Rust error is a subclass of :class:`nimbus.Error` with the CLI's one-line message.
USD stages composed by Pixar's library (PyPI ``usd-core``) render through :func:`load_stage`.
"""

from __future__ import annotations

import json
import os
import tempfile
import warnings
from typing import Any, Callable, Dict, Iterable, Optional, Sequence, Tuple, Union

import numpy as np

from . import _nimbus
from ._nimbus import (
    Error,
    FarmError,
    OutputError,
    RegionError,
    RenderError,
    Scene,
    SceneError,
    VdbError,
    __version__,
)

__all__ = [
    "Error",
    "FarmError",
    "Image",
    "NimbusWarning",
    "OutputError",
    "RegionError",
    "RenderError",
    "Scene",
    "SceneError",
    "VdbError",
    "info",
    "load",
    "load_stage",
    "merge",
    "render",
    "__version__",
]

PathLike = Union[str, "os.PathLike[str]"]


class NimbusWarning(UserWarning):
    """A loader's warning (an unknown key, an unsupported feature, a USD composition error): the scene loads."""


class Image:
    """A rendered image: every layer of its EXR as NumPy arrays, and the render's statistics.

    Attributes:
        layers: ``{name: float32 array of height x width x components}``, one entry per EXR layer: ``beauty``
            (``R, G, B, A``; the EXR's unnamed layer), ``albedo``, ``normal``, ``depth``, ``variance`` and the
            compositing layers the render wrote (light paths, light groups, Cryptomatte...).
        components: ``{name: (component names...)}`` in the arrays' last-axis order.
        stats: the ``nimbus render --stats`` dictionary.
        metadata: the EXR header's ``nimbus/`` keys.
    """

    def __init__(self, raw: "_nimbus.RawImage") -> None:
        self._raw = raw
        self._layers: Optional[Dict[str, np.ndarray]] = None
        self._components: Dict[str, Tuple[str, ...]] = {}
        self.stats: Dict[str, Any] = json.loads(raw.stats_json)
        self.metadata: Dict[str, str] = dict(raw.metadata)

    @property
    def width(self) -> int:
        """Width in pixels (of the crop window, for a part)."""
        return self._raw.width

    @property
    def height(self) -> int:
        """Height in pixels (of the crop window, for a part)."""
        return self._raw.height

    @property
    def is_part(self) -> bool:
        """Whether this is a farm part (rendered with ``samples`` or ``crop``), for :func:`merge`."""
        return self._raw.is_part

    @property
    def layers(self) -> Dict[str, np.ndarray]:
        """Every layer of the EXR as a float32 array of height x width x components (made on first use)."""
        if self._layers is None:
            layers = {}
            for name, components, data in self._raw.layers():
                array = np.frombuffer(data, dtype=np.float32)
                layers[name] = array.reshape(self.height, self.width, len(components))
                self._components[name] = tuple(components)
            self._layers = layers
        return self._layers

    @property
    def components(self) -> Dict[str, Tuple[str, ...]]:
        """The component names of each layer (``{"beauty": ("R", "G", "B", "A"), "normal": ("X", "Y", "Z")...}``)."""
        self.layers
        return dict(self._components)

    def write(self, path: PathLike) -> None:
        """Writes the EXR as ``nimbus render`` does (a part: the part file ``nimbus merge`` reads)."""
        self._raw.write(os.fspath(path))

    def to_png(self, path: PathLike, exposure: Optional[float] = 0.0) -> None:
        """Writes an 8-bit sRGB PNG of the beauty, exposed by ``exposure`` stops (``None``: metered, as
        ``--exposure auto``)."""
        self._raw.write_png(os.fspath(path), exposure)

    def _repr_png_(self) -> bytes:
        """The PNG a Jupyter notebook shows (exposure 0)."""
        with tempfile.TemporaryDirectory(prefix="nimbus-") as folder:
            return _nimbus.png_bytes(self._raw, 0.0, os.path.join(folder, "preview.png"))

    def __repr__(self) -> str:
        kind = "part" if self.is_part else "image"
        return f"<nimbus.Image {kind} {self.width}x{self.height}, {self.stats.get('samples_per_pixel')} spp>"


def load(
    path: PathLike,
    frame: Optional[int] = None,
    fps: Optional[float] = None,
    volume_method: Optional[str] = None,
    *,
    variant: Optional[str] = None,
    subdivision_level: Optional[int] = None,
    strict: bool = False,
    camera: Optional[str] = None,
    memory_limit: Optional[int] = None,
) -> Scene:
    """Loads a scene file (``.gltf``, ``.glb``, ``.obj``, ``.usd``, ``.usda``, ``.usdc``, ``.usdz``) as
    ``nimbus render`` does.

    Args:
        path: the scene file.
        frame: the shot's frame (VDB sequences, glTF animation, USD time codes).
        fps: frames per second (default: a USD stage's own, else 24).
        volume_method: override for every VDB volume, as ``nimbus converge`` names them: ``global-majorant``,
            ``grid16-majorant``, ``adaptive-majorant``, ``ratio-shadow``, ``residual-ratio-shadow``,
            ``no-media-mis`` (``default``: as the file says).
        variant: glTF material variant (``KHR_materials_variants``).
        subdivision_level: Catmull-Clark levels of USD subdivision meshes.
        strict: refuse unknown ``nimbus_*`` keys instead of warning.
        camera: the scene camera to render from, by name.
        memory_limit: bytes any one allocation sized by a file may take (default: half the physical memory).

    A scene without lighting of its own gets the CLI's uniform white environment. The loader's warnings are
    issued as :class:`NimbusWarning`.

    Raises:
        SceneError: the file cannot be loaded (the message names it and the problem).
        ValueError: an option is out of range.
    """
    scene = _nimbus.load(
        os.fspath(path),
        frame=frame,
        fps=fps,
        volume_method=volume_method,
        variant=variant,
        subdivision_level=subdivision_level,
        strict=strict,
        camera=camera,
        memory_limit=memory_limit,
    )
    _warn(scene.warnings)
    return scene


def _warn(messages: Iterable[str]) -> None:
    for message in messages:
        warnings.warn(message, NimbusWarning, stacklevel=3)


def render(
    scene: Scene,
    spp: Optional[int] = 64,
    width: Optional[int] = None,
    height: Optional[int] = None,
    seed: int = 0,
    threads: int = 0,
    time_limit: Optional[float] = None,
    samples: Optional[Tuple[int, int]] = None,
    crop: Optional[Tuple[int, int, int, int]] = None,
    progress: Optional[Callable[[int, int], Any]] = None,
    *,
    max_depth: Optional[int] = None,
    aovs: Optional[str] = None,
    transparent: bool = False,
    guiding: Optional[str] = None,
) -> Image:
    """Renders ``scene``: the same image as ``nimbus render`` with the same options and seed, bit for bit.

    Args:
        scene: from :func:`load` or :func:`load_stage`.
        spp: samples per pixel; ``None`` with ``time_limit``: as many as the time allows.
        width: image width (default 640).
        height: image height (default: from the camera's aspect ratio, else 3/4 of the width).
        seed: seed of the random streams.
        threads: worker threads (0: all cores); the image does not depend on it.
        time_limit: seconds to render progressively for, then return what there is.
        samples: ``(start, end)``: render only these samples of each pixel, as a farm part for :func:`merge`.
        crop: ``(x0, y0, x1, y1)``: render only these pixels (0, 0 = top left), as a farm part.
        progress: called as ``progress(samples_done, samples_total)`` from this thread, at most ten times a
            second; an exception it raises cancels the render and propagates.
        max_depth: scattering events per path (default: the scene's own, else 64).
        aovs: the layers beyond beauty and alpha, as ``--aovs`` takes them (``"default,lightgroups"``).
        transparent: leave the environment seen directly out of the beauty.
        guiding: path guiding, as ``--guiding`` takes it: ``"auto"`` (the default: guided where a pilot of
            unguided paths finds that it pays), ``"on"`` or ``"off"``.

    The GIL is released while the render runs. Ctrl-C cancels it within a fraction of a second and raises
    KeyboardInterrupt.

    Raises:
        RegionError: ``crop`` or ``samples`` do not fit the frame.
        RenderError: the render cannot start (memory budget, unknown light group in ``aovs``).
        ValueError: an option is out of range, or ``guiding`` is not ``"auto"``, ``"on"`` or ``"off"``.
    """
    if spp is None and time_limit is None:
        raise ValueError("spp=None needs a time_limit")
    raw = _nimbus.render(
        scene,
        spp=spp,
        width=width,
        height=height,
        seed=seed,
        threads=threads,
        time_limit=time_limit,
        samples=tuple(samples) if samples is not None else None,
        crop=tuple(crop) if crop is not None else None,
        progress=progress,
        max_depth=max_depth,
        aovs=aovs,
        transparent=transparent,
        guiding=guiding,
    )
    return Image(raw)


def info(path: PathLike) -> Dict[str, Any]:
    """The grids of a VDB file as ``nimbus info --json`` prints them.

    Raises:
        VdbError: the file is not a readable VDB file.
    """
    return json.loads(_nimbus.info_json(os.fspath(path)))


def merge(parts: Sequence[Union[Image, PathLike]]) -> Image:
    """Merges farm parts (part :class:`Image` objects and/or part files) into the image one render would have
    made, bit for bit, as ``nimbus merge`` does.

    Raises:
        FarmError: the parts do not belong together, overlap or leave a gap (the message names them).
    """
    parts = list(parts)
    with tempfile.TemporaryDirectory(prefix="nimbus-merge-") as folder:
        paths = []
        for i, part in enumerate(parts):
            if isinstance(part, Image):
                if not part.is_part:
                    raise ValueError(f"parts[{i}] is a whole image, not a part (render with samples= or crop=)")
                path = os.path.join(folder, f"part{i}.exr")
                part.write(path)
                paths.append(path)
            else:
                paths.append(os.fspath(part))
        return Image(_nimbus.merge(paths))


def load_stage(stage: Any, time: Optional[float] = None, **options: Any) -> Scene:
    """Loads a ``pxr.Usd.Stage`` (PyPI ``usd-core``) that Pixar's library has composed: references, payloads,
    variant selections, sublayers, inherits and specializes are resolved by USD itself, and the flattened
    stage (``stage.Flatten()``) is read by Nimbus's own USD reader.

    Args:
        stage: an open ``pxr.Usd.Stage``.
        time: the whole frame to read animated values at, as :func:`load`'s ``frame`` (the time code itself
            when the stage's timeCodesPerSecond equals its framesPerSecond, as usual); default: the stage's
            default values.
        options: as :func:`load` takes them (``frame``, ``fps``, ``camera``...).

    Composition errors USD reports (a missing reference, a layer that cannot be opened) do not stop the
    stage: each is issued as a :class:`NimbusWarning`, and the rest of the stage renders.

    Raises:
        ImportError: ``usd-core`` is not installed (``pip install usd-core``).
        SceneError: the flattened stage cannot be read.
    """
    try:
        from pxr import Usd
    except ImportError as e:
        raise ImportError(
            "nimbus.load_stage needs Pixar's USD library: pip install usd-core (the PyPI package 'usd-core')"
        ) from e
    if not isinstance(stage, Usd.Stage):
        raise TypeError(f"load_stage takes a pxr.Usd.Stage, not {type(stage).__name__}")
    errors = _composition_errors(stage)
    messages = [f"USD composition: {e}" for e in errors[:1]]
    if len(errors) > 1:
        messages[0] += f" (and {len(errors) - 1} more composition errors: stage.GetCompositionErrors() lists them)"
    if time is not None:
        if "frame" in options:
            raise ValueError("give load_stage a time or a frame, not both")
        frame = float(time)
        if not frame.is_integer():
            raise ValueError(f"time {time} must be a whole time code (Nimbus reads whole frames)")
        options["frame"] = int(frame)
    text = stage.Flatten().ExportToString()
    root = stage.GetRootLayer()
    label = f"{root.identifier} (composed by usd-core)"
    with tempfile.TemporaryDirectory(prefix="nimbus-stage-") as folder:
        path = os.path.join(folder, "flattened.usda")
        with open(path, "w", encoding="utf-8") as f:
            f.write(text)
        scene = _nimbus.load(
            path,
            source_text=text.encode("utf-8"),
            source_label=label,
            **options,
        )
    _warn(messages + list(scene.warnings))
    return scene


def _composition_errors(stage: Any) -> Sequence[str]:
    """USD's own composition errors of ``stage``, one line each (empty for a USD without the query)."""
    get = getattr(stage, "GetCompositionErrors", None)
    if get is None:
        return []
    return [" ".join(str(error).split()) for error in get()]
