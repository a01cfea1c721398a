"""Type stub of the scalemesh extension module (src/python/module.cpp).

Installed beside the module (scalemesh.cpython-*.so), so that type checkers
and editors show the arguments and results; tests/python checks that it names
what the module defines.
"""

import os
from collections.abc import Callable, ItemsView, Iterator, KeysView, Mapping, Sequence, ValuesView
from typing import Any, Literal, TypedDict, Union

import numpy as np
import numpy.typing as npt

# A length: a number of mm, or a string "2 mm" / "0.5 voxels".
Length = Union[float, str]
PathLike = Union[str, bytes, os.PathLike[str], os.PathLike[bytes]]
Vector3 = Union[Sequence[float], npt.NDArray[np.float64]]


class Opening(TypedDict, total=False):
    """One [[openings]] table of the case file (docs/case-file.md)."""

    name: str  # the patch: letters, digits and '_', not a digit first, not "wall"
    type: Literal["inlet", "outlet"]
    point: Vector3  # clip plane: a point inside the lumen (mm)
    normal: Vector3  # clip plane: its normal, out of the lumen
    radius: float  # clip plane: mm; 0: the plane crosses the lumen once
    border: Literal["x-", "x+", "y-", "y+", "z-", "z+"]  # a side of the image
    inset: Length  # border openings; "auto" (the default)
    near: Vector3  # an open end of the surface: the one nearest this point (mm)
    label: int  # a flat cap of a surface file's face labels
    extension: float  # flow extension, in cap diameters; 0: none


class OpenFoamCase(TypedDict):
    """What MeshResult.write_openfoam wrote."""

    cells: int
    faces: int
    internal_faces: int
    layer_prisms: int
    patch_names: list[str]
    patch_faces: list[int]
    flow_fields: bool  # 0/U and 0/p written (an inlet and an outlet)
    warnings: list[str]


class MeshResult(Mapping[str, Any]):
    """The layered tetrahedral mesh (mm) and the run that made it.

    A read-only mapping of NumPy arrays: points (N, 3), tets (T, 4),
    boundary_triangles (B, 3), boundary_patch (B,), patch_names, surface_points,
    D, D_out, d, layers, point_layer, point_generator, point_filler (N,),
    aspect_ratio, tet_layer (T,); from mesh_gmsh_model also volume,
    patch_surfaces, volume_group, patch_groups, first_node_tag, first_tet_tag,
    views, removed_volumes.
    """

    def __getitem__(self, key: str) -> Any: ...
    def __contains__(self, key: object) -> bool: ...
    def __iter__(self) -> Iterator[str]: ...
    def __len__(self) -> int: ...
    def keys(self) -> KeysView[str]: ...
    def values(self) -> ValuesView[Any]: ...
    def items(self) -> ItemsView[str, Any]: ...
    def get(self, key: str, default: Any = None) -> Any: ...
    @property
    def report(self) -> dict[str, Any]:
        """report.json of `scalemesh run` for a run that wrote no files, as a dict."""
    @property
    def layers_built(self) -> Literal["prisms", "delaunay"]:
        """The layers the run built: the layers option, or "delaunay" where prism layers were given up."""
    def report_json(self) -> str:
        """The report as JSON text."""
    def write_openfoam(
        self,
        case_dir: PathLike,
        *,
        viscosity: float = 3.3e-6,
        inlet_speed: float = 0.1,
        binary: bool = False,
        layer_prisms: bool = True,
    ) -> OpenFoamCase:
        """Writes the OpenFOAM case (polyMesh, system/, 0/, Allrun, report.json) as `scalemesh run` does."""
    def write_msh(
        self, path: PathLike, *, version: float = 4.1, binary: bool = False, gmsh_session: bool = False
    ) -> None:
        """Writes the volume mesh (.msh) with physical groups and views as `scalemesh run` writes mesh.msh."""
    def to_meshio(self) -> Any:
        """The mesh as a meshio.Mesh (needs the meshio package)."""


def mesh_surface(
    points: npt.ArrayLike | Any | tuple[npt.ArrayLike, npt.ArrayLike],
    triangles: npt.ArrayLike | None = None,
    labels: npt.ArrayLike | None = None,
    *,
    node_tags: npt.ArrayLike | None = None,
    label_names: Sequence[str] | None = None,
    K: float = ...,
    M: float = ...,
    G: float = ...,
    L_min: Length = ...,
    L_max: Length | None = ...,
    curvature: bool = ...,
    smoothing_sweeps: int = ...,
    smoothing_omega: float = ...,
    smoothing_reach: Length = ...,
    remesh_cycles: int = ...,
    growth: float = ...,
    first_layer: Literal["edge", "paper"] = ...,
    layers: Literal["delaunay", "prisms"] = ...,
    layer_tolerance: float = ...,
    threads: int = ...,
    max_memory: int = ...,
    openings: Sequence[Opening] | None = ...,
    progress: Callable[[str, float, str], None] | None = ...,
    gmsh_session: bool = ...,
) -> MeshResult:
    """Meshes a closed or open-ended triangulated surface (mm) as `scalemesh run` meshes a surface file.

    points: (N, 3) coordinates with triangles (M, 3) 0-based indices; or a
    tuple (points, triangles); or a meshio.Mesh, whose "triangle" cells are
    the surface (vertex and line cells left out, other cells refused).
    """


def mesh_image(
    image: PathLike | npt.NDArray[Any],
    spacing: float | Sequence[float] | None = None,
    origin: Sequence[float] | None = None,
    labels: int | Sequence[int] | None = None,
    *,
    threshold: float | None = None,
    level_set: bool = False,
    iso: float | None = None,
    connectivity: Literal[6, 26] = 6,
    grid: str | None = None,
    units: Literal["mm", "cm", "m", "um"] = "mm",
    K: float = ...,
    M: float = ...,
    G: float = ...,
    L_min: Length = ...,
    L_max: Length | None = ...,
    curvature: bool = ...,
    smoothing_sweeps: int = ...,
    smoothing_omega: float = ...,
    smoothing_reach: Length = ...,
    remesh_cycles: int = ...,
    growth: float = ...,
    first_layer: Literal["edge", "paper"] = ...,
    layers: Literal["delaunay", "prisms"] = ...,
    layer_tolerance: float = ...,
    threads: int = ...,
    max_memory: int = ...,
    openings: Sequence[Opening] | None = ...,
    progress: Callable[[str, float, str], None] | None = ...,
    gmsh_session: bool = ...,
) -> MeshResult:
    """Meshes an image file, or a 3-D array vol[i, j, k], as `scalemesh run` meshes an image file.

    An array's voxel (i, j, k) is centred at origin + (i sx, j sy, k sz) mm
    (spacing (sx, sy, sz) needed, origin default (0, 0, 0)), whatever its
    memory order; bool, (u)int8 to (u)int64, float32 or float64 voxels. It
    meshes exactly as a MetaImage of the same voxels with Offset = origin and
    ElementSpacing = spacing.
    """


def mesh_gmsh_model(
    physical_group: str | None = None,
    *,
    volume_name: str = "fluid",
    views: bool = True,
    K: float = ...,
    M: float = ...,
    G: float = ...,
    L_min: Length = ...,
    L_max: Length | None = ...,
    curvature: bool = ...,
    smoothing_sweeps: int = ...,
    smoothing_omega: float = ...,
    smoothing_reach: Length = ...,
    remesh_cycles: int = ...,
    growth: float = ...,
    first_layer: Literal["edge", "paper"] = ...,
    layers: Literal["delaunay", "prisms"] = ...,
    layer_tolerance: float = ...,
    threads: int = ...,
    max_memory: int = ...,
    progress: Callable[[str, float, str], None] | None = ...,
) -> MeshResult:
    """Meshes the surface of the current gmsh.py model and adds the volume mesh to it."""


def defaults() -> dict[str, Any]:
    """The default options: those of the case file scalemesh.toml."""
