"""Type stubs of the extension module ``nimbus._nimbus`` (python/src/lib.rs); the API is ``nimbus``'s."""

from typing import Callable, Dict, List, Optional, Tuple

__version__: str

class Error(Exception):
    """Any error of Nimbus; each Rust error type is one subclass, with the same one-line message."""

class SceneError(Error):
    """A scene file could not be loaded (names the file and the problem)."""

class OutputError(Error):
    """An image could not be written or read."""

class VdbError(Error):
    """A VDB file could not be read."""

class RegionError(Error):
    """A render's crop window or sample range does not fit the frame."""

class FarmError(Error):
    """Farm parts could not be written or merged (parts of different renders, overlaps, gaps)."""

class RenderError(Error):
    """A render could not start: its worker threads, a film over the memory budget, layers that cannot be made."""

class Scene:
    """A loaded scene, ready to render any number of times (from any thread)."""

    @property
    def warnings(self) -> List[str]:
        """The loader's warnings, one line each."""
    @property
    def triangle_count(self) -> int:
        """Number of triangles after instancing."""
    @property
    def source(self) -> str:
        """The file the scene was loaded from (a flattened USD stage: what it was composed from)."""
    @property
    def aspect_ratio(self) -> Optional[float]:
        """The camera's width / height, if the scene gives one."""

class RawImage:
    """A rendered image or farm part (``nimbus.Image`` wraps it)."""

    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def is_part(self) -> bool: ...
    @property
    def stats_json(self) -> str:
        """The ``--stats`` JSON text."""
    @property
    def metadata(self) -> Dict[str, str]:
        """The EXR header's ``nimbus/`` keys."""
    def layers(self) -> List[Tuple[str, List[str], bytearray]]:
        """(name, component names, interleaved float32 samples) of every EXR layer."""
    def write(self, path: str) -> None:
        """Writes the EXR (a part: the part file)."""
    def write_png(self, path: str, exposure: Optional[float] = 0.0) -> None:
        """Writes the 8-bit sRGB preview (``None``: metered exposure)."""

def load(
    path: str,
    frame: Optional[int] = None,
    fps: Optional[float] = None,
    volume_method: Optional[str] = None,
    variant: Optional[str] = None,
    subdivision_level: Optional[int] = None,
    strict: bool = False,
    camera: Optional[str] = None,
    memory_limit: Optional[int] = None,
    source_text: Optional[bytes] = None,
    source_label: Optional[str] = None,
) -> Scene:
    """Loads a scene file as ``nimbus render`` does."""

def render(
    scene: Scene,
    spp: Optional[int] = None,
    width: Optional[int] = None,
    height: Optional[int] = None,
    seed: int = 0,
    threads: int = 0,
    time_limit: Optional[float] = None,
    samples: Optional[Tuple[int, int]] = None,
    crop: Optional[Tuple[int, int, int, int]] = None,
    progress: Optional[Callable[[int, int], object]] = None,
    max_depth: Optional[int] = None,
    aovs: Optional[str] = None,
    transparent: bool = False,
    guiding: Optional[str] = None,
) -> RawImage:
    """Renders as ``nimbus render`` does, with the GIL released."""

def info_json(path: str) -> str:
    """The ``nimbus info --json`` text of a VDB file."""

def merge(paths: List[str]) -> RawImage:
    """Merges part files as ``nimbus merge`` does."""

def png_bytes(image: RawImage, exposure: float, scratch: str) -> bytes:
    """The PNG preview as bytes, written through the file ``scratch``."""
