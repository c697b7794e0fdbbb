"""Type hints of the compiled half of the package (see python/src/lib.rs); users call
it through the documented wrappers in raypack/__init__.py, which check and convert
their arguments first."""

from typing import Optional, Tuple

import numpy as np

MAX_GI_SPP: int

class Error(ValueError): ...

_Vec3 = Tuple[float, float, float]
_HitArrays = Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]

class Scene:
    @staticmethod
    def from_arrays(
        vertices: np.ndarray, triangles: np.ndarray, threads: int, accel: str
    ) -> "Scene": ...
    @staticmethod
    def load(scene: str, threads: int, accel: str) -> "Scene": ...
    @property
    def accel(self) -> str: ...
    @property
    def last_accel(self) -> Tuple[str, str]: ...
    @property
    def triangle_count(self) -> int: ...
    @property
    def primitive_count(self) -> int: ...
    @property
    def bounds(self) -> Tuple[_Vec3, _Vec3]: ...
    @property
    def camera(self) -> Tuple[_Vec3, _Vec3, _Vec3, float]: ...
    @property
    def warnings(self) -> list[str]: ...
    def intersect(
        self, origins: np.ndarray, directions: np.ndarray, t_min: np.ndarray, t_max: np.ndarray,
        threads: int, mode: str,
    ) -> _HitArrays: ...
    def occluded(
        self, origins: np.ndarray, directions: np.ndarray, t_min: np.ndarray, t_max: np.ndarray,
        threads: int, mode: str,
    ) -> np.ndarray: ...
    def camera_rays(
        self, eye: _Vec3, target: _Vec3, up: _Vec3, vfov: float, width: int, height: int
    ) -> Tuple[np.ndarray, np.ndarray]: ...
    def trace_image(
        self, eye: _Vec3, target: _Vec3, up: _Vec3, vfov: float, width: int, height: int,
        threads: int, mode: str,
    ) -> _HitArrays: ...

def isa() -> str: ...
def render(
    scene: Scene, width: Optional[int], height: Optional[int], spp: Optional[int],
    integrator: str, camera: Optional[Tuple[_Vec3, _Vec3, _Vec3, float]],
    sky: Optional[_Vec3], seed: Optional[int], threads: int, mode: str, photons: int,
    max_bounces: Optional[int], sampler: str,
) -> np.ndarray: ...
