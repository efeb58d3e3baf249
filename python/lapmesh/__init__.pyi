# Type stubs of the lapmesh package. Option defaults are the library's (shown as `...`): see
# help(lapmesh.<function>) or `lapmesh <command> --help`; accepted names: lapmesh.names(kind).
from typing import Any, Callable, Dict, List, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

ArrayLike = npt.ArrayLike
Float64 = npt.NDArray[np.float64]
Int64 = npt.NDArray[np.int64]

class LapmeshWarning(UserWarning): ...

class MeshError(ValueError):
    element: Optional[str]  # 'vertex', 'face', 'edge' or None
    index: int  # -1 if none
    def __init__(self, message: str, element: Optional[str] = ..., index: int = ...) -> None: ...

class NumericalError(RuntimeError): ...
class IoError(OSError): ...

class ParameterError(ValueError):
    parameter: Optional[str]  # the keyword argument at fault
    suggested_value: Union[str, bool, None]
    def __init__(self, message: str, parameter: Optional[str] = ..., suggested_value: Union[str, bool, None] = ...) -> None: ...

def names(kind: str) -> List[str]: ...
def describe(kind: str) -> Dict[str, str]: ...
def read_mesh(path: str) -> Tuple[Float64, Int64]: ...
def write_mesh(path: str, V: ArrayLike, F: ArrayLike) -> None: ...

class Curvatures:
    @property
    def mean(self) -> Float64: ...
    @property
    def gaussian(self) -> Float64: ...
    @property
    def k1(self) -> Float64: ...
    @property
    def k2(self) -> Float64: ...
    @property
    def area(self) -> Float64: ...
    @property
    def normal(self) -> Float64: ...
    @property
    def laplacian(self) -> Float64: ...

def curvatures(V: ArrayLike, F: ArrayLike, *, laplacian: str = ..., area: str = ...) -> Curvatures: ...
def laplacian(V: ArrayLike, F: ArrayLike, *, laplacian: str = ..., area: str = ...) -> Tuple[Any, Float64]: ...
def laplacian_arrays(
    V: ArrayLike, F: ArrayLike, *, laplacian: str = ..., area: str = ...
) -> Tuple[Float64, Int64, Int64, int, Float64]: ...

class SpectralBasis:
    def __init__(
        self,
        V: ArrayLike,
        F: ArrayLike,
        k: int,
        *,
        laplacian: str = ...,
        area: str = ...,
        progress: Optional[Callable[[str, int, int, float], None]] = ...,
    ) -> None: ...
    @property
    def values(self) -> Float64: ...
    @property
    def vectors(self) -> Float64: ...
    @property
    def mass(self) -> Float64: ...
    @property
    def k(self) -> int: ...
    @property
    def laplacian(self) -> str: ...
    @property
    def area(self) -> str: ...
    def __len__(self) -> int: ...
    def reconstruct(self, k: int) -> Float64: ...
    def project(self, signal: ArrayLike, k: int) -> Float64: ...
    def save(self, path: str) -> None: ...
    @staticmethod
    def load(path: str, V: Optional[ArrayLike] = ..., F: Optional[ArrayLike] = ...) -> "SpectralBasis": ...

def smooth(
    V: ArrayLike,
    F: ArrayLike,
    *,
    scheme: str = ...,
    lam: Union[str, float] = ...,
    lambda_unit: str = ...,
    iterations: int = ...,
    laplacian: str = ...,
    area: str = ...,
    fixed_operator: bool = ...,
    restore_volume: bool = ...,
    restore_area: bool = ...,
    fix_boundary: bool = ...,
    reuse_factorization: bool = ...,
    progress: Optional[Callable[[int, int], None]] = ...,
) -> Tuple[Float64, Dict[str, Any]]: ...
def add_noise(
    V: ArrayLike, F: ArrayLike, *, level: float = ..., seed: int = ..., direction: str = ..., scale: str = ...
) -> Float64: ...
def denoise_study(
    V: ArrayLike,
    F: ArrayLike,
    *,
    levels: List[float] = ...,
    schemes: List[str] = ...,
    laplacians: List[str] = ...,
    lambdas: List[float] = ...,
    lambda_unit: str = ...,
    iterations: int = ...,
    seed: int = ...,
    direction: str = ...,
    area: str = ...,
    restore_volume: bool = ...,
    fixed_operator: bool = ...,
    hausdorff_spacing: float = ...,
) -> Dict[str, Any]: ...
