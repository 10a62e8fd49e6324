"""psr: screened Poisson surface reconstruction, through libpsr's C ABI.

    >>> import psr
    >>> cloud = psr.read_ply("cloud.ply")                 # or NumPy arrays, or an Open3D cloud
    >>> mesh = psr.reconstruct(cloud.points, cloud.normals, depth=9)
    >>> mesh.vertices, mesh.triangles, mesh.densities     # NumPy arrays
    >>> mesh.write_ply("mesh.ply")

:func:`reconstruct` does one cloud; a :class:`Reconstructor` keeps parameters for many clouds
and adds points in batches; :func:`reconstruct_out_of_core` reconstructs a PLY file into a PLY
file without holding the whole cloud or its mesh in memory. Errors are :class:`PsrError`
subclasses carrying psr's :class:`Status` and message. The shared library inside the package
is loaded with ctypes: no compiler is needed at import time, and the GIL is released while psr
works.
"""

from __future__ import annotations

from ._core import (
    DEFAULTS,
    Boundary,
    Implicit,
    Mesh,
    Orientation,
    OutOfCoreReport,
    ProgressCallback,
    Reconstructor,
    SolveStats,
    Splatting,
    Stage,
    TrimThreshold,
    VertexPlacement,
    reconstruct,
    reconstruct_out_of_core,
)
from ._errors import (
    CancelledError,
    EmptyInputError,
    FileError,
    HandlePoisonedError,
    InternalError,
    InvalidArgumentError,
    InvalidParameterError,
    InvalidTransformError,
    InvalidWeightError,
    NonFiniteError,
    OutOfMemoryError,
    PlyError,
    PsrError,
    Status,
    ThreadsUnavailableError,
    TooLargeError,
    ZeroNormalError,
)
from ._lib import LIB as _LIB
from ._lib import library_path
from ._ply import PlyMesh, PointCloud, read_ply, read_ply_mesh, write_ply

#: The version of the loaded libpsr ("MAJOR.MINOR.PATCH"); the package has the same version.
library_version: str = _LIB.psr_version().decode()
__version__ = library_version

__all__ = [
    "DEFAULTS",
    "Boundary",
    "CancelledError",
    "EmptyInputError",
    "FileError",
    "HandlePoisonedError",
    "Implicit",
    "InternalError",
    "InvalidArgumentError",
    "InvalidParameterError",
    "InvalidTransformError",
    "InvalidWeightError",
    "Mesh",
    "NonFiniteError",
    "Orientation",
    "OutOfCoreReport",
    "OutOfMemoryError",
    "PlyError",
    "PlyMesh",
    "PointCloud",
    "ProgressCallback",
    "PsrError",
    "Reconstructor",
    "SolveStats",
    "Splatting",
    "Stage",
    "Status",
    "ThreadsUnavailableError",
    "TooLargeError",
    "TrimThreshold",
    "VertexPlacement",
    "ZeroNormalError",
    "library_path",
    "library_version",
    "read_ply",
    "read_ply_mesh",
    "reconstruct",
    "reconstruct_out_of_core",
    "write_ply",
]
