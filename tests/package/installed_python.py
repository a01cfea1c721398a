"""The installed Python module as a user meets it (package_test.cmake runs
this with PYTHONPATH at the install prefix's dist-packages): the shared aorta
STL through mesh_image, its OpenFOAM case through checkMesh, its meshio
mesh, and a NumPy ball of voxels. Any failed check exits non-zero.

    python3 installed_python.py <prefix> <aorta.stl>
"""
import os
import subprocess
import sys
import tempfile

import numpy as np

prefix, aorta = os.path.realpath(sys.argv[1]), sys.argv[2]
import scalemesh  # noqa: E402  (after sys.argv is read, so a usage error comes first)

module = os.path.realpath(scalemesh.__file__)
assert module.startswith(prefix + os.sep), "scalemesh imported from %s, not from the install %s" % (module, prefix)


def closed(triangles):
    """Every edge of the triangles on exactly two of them."""
    edges = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return len(triangles) > 0 and bool(np.all(counts == 2))


aorta_mesh = scalemesh.mesh_image(aorta, threads=2)
assert closed(np.asarray(aorta_mesh["boundary_triangles"])), "the aorta's boundary is not closed"
with tempfile.TemporaryDirectory() as case:
    aorta_mesh.write_openfoam(case)
    check = subprocess.run(["checkMesh", "-case", case], capture_output=True, text=True)
    assert "Mesh OK." in check.stdout, "checkMesh on the written case:\n" + check.stdout[-3000:] + check.stderr[-2000:]
print("aorta: %d tets, checkMesh Mesh OK" % len(aorta_mesh["tets"]))

as_meshio = aorta_mesh.to_meshio()
volume_cells = sum(len(block.data) for block in as_meshio.cells if block.type in ("tetra", "wedge"))
assert volume_cells > 0, "to_meshio() has no volume cells: %s" % [block.type for block in as_meshio.cells]
print("to_meshio: %d volume cells" % volume_cells)

i, j, k = np.meshgrid(*(np.arange(24),) * 3, indexing="ij")
ball = (i - 11.5) ** 2 + (j - 11.5) ** 2 + (k - 11.5) ** 2 < 10 ** 2
ball_mesh = scalemesh.mesh_image(ball, spacing=(0.5,) * 3, threads=2)
assert closed(np.asarray(ball_mesh["boundary_triangles"])), "the ball's boundary is not closed"
assert len(ball_mesh["tets"]) > 0
print("ball: %d tets, a closed boundary" % len(ball_mesh["tets"]))
