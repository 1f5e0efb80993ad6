"""Type stubs of displace (pipeline/python/module.cpp). Units: metres, seconds, milliseconds."""
from typing import Any, Iterator, Optional, Sequence, Tuple

import numpy as np
import numpy.typing as npt

class Scene:
    """A scene: keys read and set by their TOML names (scene["ocean.wind_speed"], m/s), checked as
    scene files are (KeyError: unknown key, ValueError: bad value)."""
    @staticmethod
    def builtin(name: str) -> Scene: ...
    @staticmethod
    def builtin_names() -> list[str]: ...
    @staticmethod
    def load(path: str) -> Scene: ...
    @staticmethod
    def from_toml(text: str, name: str = "python") -> Scene: ...
    def to_toml(self) -> str: ...
    def copy(self) -> Scene: ...
    @property
    def name(self) -> str: ...
    def __getitem__(self, key: str) -> Any: ...
    def __setitem__(self, key: str, value: Any) -> None: ...

def heights(scene: Scene, time: Optional[float] = None, *, normalized: bool = False) -> npt.NDArray[np.float32]:
    """float32 (H, W): metres as `displace sim` writes them, or [0, 1] with normalized=True."""

def bake(
    heights: npt.ArrayLike,
    sectors: int = 4,
    cones: str = "bilinear",
    mode: str = "budgeted",
    budget_ms: Optional[float] = None,
    address: str = "wrap",
    tolerance: float = 0.25,
) -> Tuple[npt.NDArray[np.float32], Optional[npt.NDArray[np.float32]], dict[str, Any]]:
    """(cones (H, W, sectors), apex (H, W) or None for centre cones, stats as `bake --stats`)."""

def query(scene: Scene, time: float, points: npt.ArrayLike) -> dict[str, npt.NDArray[np.float32]]:
    """height_m (N,) metres, z (N,), normal (N, 3), displacement (N, 2) metres at (N, 2) points."""

class Pipeline:
    """A scene's per-frame pipeline, as `displace sequence` runs it."""
    def __init__(self, scene: Scene, size: Optional[Tuple[int, int]] = None, backend: str = "auto") -> None: ...
    def frame(self, n: int) -> npt.NDArray[np.uint8]:
        """Frame n as uint8 (height, width, 4) RGBA, row 0 at the top."""
    def frames(self, first: int = 0, count: Optional[int] = None) -> Iterator[Tuple[int, npt.NDArray[np.uint8]]]: ...
    @property
    def stats(self) -> dict[str, Any]:
        """bench-frame --json's keys over the last frames (up to 1,000; milliseconds); "last": the last
        frame's record."""
    @property
    def scene(self) -> Scene: ...
