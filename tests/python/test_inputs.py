"""Inputs in memory from Python: mesh_image on a NumPy array vol[i, j, k] (the
same mesh as the same voxels in a MetaImage or NIfTI file, whatever the
array's memory order and voxel type), a .msh input in the host's Gmsh session,
and mesh_surface on a meshio.Mesh.

Run by ctest (test python_module) with the module's directory on PYTHONPATH.
"""

import os
import struct
import subprocess
import sys
import tempfile
import unittest

try:
    import gmsh
    import meshio
    import numpy as np
except ImportError as error:  # a missing dependency fails the run, loudly
    raise ImportError(f"{error}: install the Debian packages python3-gmsh, python3-meshio and python3-numpy (setup.sh)") from error
import scalemesh

# Spacings and origin exact in single precision, as a NIfTI header holds them.
SPACING = (0.5, 0.625, 0.75)  # mm along i, j, k
ORIGIN = (10.0, -4.0, 2.5)  # mm, the centre of vol[0, 0, 0]
SEMI_AXES = (5.5, 2.6, 2.4)  # mm: long along x (index i)


def ellipsoid(shape=(26, 12, 10), spacing=SPACING, semi_axes=SEMI_AXES):
    """A 0/1 uint8 ellipsoid centred in the array, vol[i, j, k] with i along x."""
    index = np.meshgrid(*[np.arange(n) for n in shape], indexing="ij")
    r2 = sum(((index[d] - (shape[d] - 1) / 2) * spacing[d] / semi_axes[d]) ** 2 for d in range(3))
    return (r2 < 1).astype(np.uint8)


def write_mha(path, vol, spacing, origin):
    """A MetaImage holding vol's voxels (x fastest, as the format has them)."""
    header = (
        "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
        "TransformMatrix = 1 0 0 0 1 0 0 0 1\n"
        f"Offset = {' '.join(repr(float(x)) for x in origin)}\n"
        f"ElementSpacing = {' '.join(repr(float(x)) for x in spacing)}\n"
        f"DimSize = {' '.join(str(n) for n in vol.shape)}\n"
        "ElementType = MET_UCHAR\nElementDataFile = LOCAL\n"
    )
    with open(path, "wb") as out:
        out.write(header.encode())
        out.write(np.asarray(vol, dtype=np.uint8).tobytes(order="F"))


def write_nifti(path, vol, spacing, origin):
    """A NIfTI-1 file of vol's uint8 voxels whose sform is, in ITK's LPS
    coordinates, the identity direction with the given spacing and origin
    (NIfTI's RAS x and y are LPS's negated)."""
    header = bytearray(348)
    struct.pack_into("<i", header, 0, 348)
    struct.pack_into("<8h", header, 40, 3, *vol.shape, 1, 1, 1, 1)
    struct.pack_into("<hh", header, 70, 2, 8)  # datatype uint8, 8 bits
    struct.pack_into("<8f", header, 76, 1.0, *spacing, 1, 1, 1, 1)
    struct.pack_into("<f", header, 108, 352.0)  # vox_offset
    struct.pack_into("<f", header, 112, 1.0)  # scl_slope
    struct.pack_into("<hh", header, 252, 0, 1)  # qform_code 0, sform_code 1 (scanner)
    sx, sy, sz = spacing
    ox, oy, oz = origin
    struct.pack_into("<12f", header, 280, -sx, 0, 0, -ox, 0, -sy, 0, -oy, 0, 0, sz, oz)
    header[344:348] = b"n+1\0"
    with open(path, "wb") as out:
        out.write(bytes(header) + bytes(4))
        out.write(np.asarray(vol, dtype=np.uint8).tobytes(order="F"))


class TestMeshImageArray(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.vol = ellipsoid()
        cls.result = scalemesh.mesh_image(cls.vol, spacing=SPACING, origin=ORIGIN, threads=2)

    def same_points(self, result):
        np.testing.assert_array_equal(result["points"], self.result["points"])
        np.testing.assert_array_equal(result["tets"], self.result["tets"])

    def test_layers_built_says_which_layers_the_run_built(self):
        self.assertEqual(self.result.layers_built, "prisms")  # the default layers, built
        self.assertEqual(self.result.layers_built, self.result.report["volume"]["layers_built"])
        with self.assertRaises(AttributeError):
            self.result.layers_built = "delaunay"  # read-only
        paper = scalemesh.mesh_image(self.vol, spacing=SPACING, origin=ORIGIN, threads=2, layers="delaunay")
        self.assertEqual(paper.layers_built, "delaunay")

    def test_the_first_index_runs_along_x(self):
        points = self.result["points"]
        low, high = points.min(axis=0), points.max(axis=0)
        shape = np.array(self.vol.shape)
        centre = np.array(ORIGIN) + (shape - 1) / 2 * np.array(SPACING)
        np.testing.assert_allclose((low + high) / 2, centre, atol=max(SPACING))
        # Each half-extent within a voxel of its semi-axis: 5.5 mm along x.
        np.testing.assert_allclose((high - low) / 2, SEMI_AXES, atol=max(SPACING))
        self.assertEqual(int(np.argmax(high - low)), 0)
        self.assertGreater(len(self.result["tets"]), 0)

    def test_the_same_voxels_in_a_file_give_the_same_mesh(self):
        with tempfile.TemporaryDirectory() as scratch:
            mha = os.path.join(scratch, "ellipsoid.mha")
            write_mha(mha, self.vol, SPACING, ORIGIN)
            self.same_points(scalemesh.mesh_image(mha, threads=2))
            nii = os.path.join(scratch, "ellipsoid.nii")
            write_nifti(nii, self.vol, SPACING, ORIGIN)
            self.same_points(scalemesh.mesh_image(nii, threads=2))
            with self.assertRaisesRegex(ValueError, "header holds them"):
                scalemesh.mesh_image(mha, spacing=SPACING)

    def test_memory_order_and_voxel_type_change_nothing(self):
        vol = self.vol
        for other in (np.asfortranarray(vol), vol.astype(bool), vol.astype(np.int16), vol.astype(">i2"),
                      vol.astype(np.int32), vol.astype(np.float32), vol.astype(np.float64)):
            with self.subTest(dtype=str(other.dtype), fortran=bool(other.flags.f_contiguous)):
                self.same_points(scalemesh.mesh_image(other, spacing=SPACING, origin=ORIGIN, threads=2))
        # A strided view (every other voxel along i) and a reversed one: as their copies.
        for view in (vol[::2], vol[:, ::-1, :]):
            with self.subTest(strides=view.strides):
                np.testing.assert_array_equal(
                    scalemesh.mesh_image(view, spacing=SPACING, origin=ORIGIN, threads=2)["points"],
                    scalemesh.mesh_image(view.copy(), spacing=SPACING, origin=ORIGIN, threads=2)["points"])

    def test_broadcast_and_misaligned_arrays_mesh_as_their_copies(self):
        # A view whose strides are all 0 (one voxel broadcast) and one whose
        # data starts one byte into its buffer: read as their packed copies.
        def outcome(vol):
            try:
                return "meshed", scalemesh.mesh_image(vol, spacing=SPACING, threads=2)["points"].tobytes()
            except ValueError as e:
                return "refused", str(e)

        everywhere = np.broadcast_to(np.uint8(1), (8, 8, 8))
        self.assertEqual(everywhere.strides, (0, 0, 0))
        self.assertEqual(outcome(everywhere), outcome(everywhere.copy()))
        ball = np.zeros((12, 12, 12), dtype=np.uint8)
        ball[3:9, 3:9, 3:9] = 1
        raw = bytearray(1 + 2 * ball.size)
        raw[1:] = ball.astype("<i2").tobytes()
        misaligned = np.frombuffer(bytes(raw), dtype="<i2", offset=1).reshape(ball.shape)
        self.assertFalse(misaligned.flags.aligned)
        first = outcome(misaligned)
        self.assertEqual(first[0], "meshed")
        self.assertEqual(first, outcome(ball))

    def test_labels_threshold_and_level_set_read_as_for_a_file(self):
        # Label 2 is the ellipsoid's x > centre half, label 1 the rest of it.
        labelled = self.vol.astype(np.int32)
        labelled[self.vol.shape[0] // 2:][labelled[self.vol.shape[0] // 2:] == 1] = 2
        half = scalemesh.mesh_image(labelled, spacing=SPACING, origin=ORIGIN, labels=[2], threads=2)
        centre_x = ORIGIN[0] + (self.vol.shape[0] - 1) / 2 * SPACING[0]
        self.assertGreater(half["points"][:, 0].min(), centre_x - SPACING[0])
        self.same_points(scalemesh.mesh_image(labelled, spacing=SPACING, origin=ORIGIN, labels=[1, 2], threads=2))
        self.same_points(scalemesh.mesh_image(labelled * 100.0, spacing=SPACING, origin=ORIGIN, threshold=50,
                                              threads=2))
        # A signed distance, negative inside: a sphere of radius 3 mm.
        index = np.meshgrid(*[np.arange(16)] * 3, indexing="ij")
        distance = np.sqrt(sum((index[d] - 7.5) ** 2 for d in range(3))) * 0.5 - 3.0
        sphere = scalemesh.mesh_image(distance, spacing=0.5, level_set=True, threads=2)
        radius = np.linalg.norm(sphere["points"][: sphere["surface_points"]] - 3.75, axis=1)
        np.testing.assert_allclose(radius, 3.0, atol=0.25)

    def test_bad_arrays_raise_one_error_saying_what_to_do(self):
        vol = self.vol
        cases = [
            (ValueError, r"has 2 dimensions \(shape \(12, 10\)\); a 3-D volume", lambda: vol[0]),
            (ValueError, "spacing 0 along axis 1; spacings must be positive", lambda: vol, {"spacing": (1, 0, 1)}),
            (ValueError, "spacing -1 along axis 0", lambda: vol, {"spacing": -1}),
            (ValueError, "spacing is not 3 numbers", lambda: vol, {"spacing": (1, 1)}),
            (ValueError, "no nonzero voxel", lambda: np.zeros_like(vol)),
            (ValueError, "label 3 not present in the image; labels present: 0, 1", lambda: vol, {"labels": 3}),
            (TypeError, "holds float16 values, which are not read. Hint: give bool, uint8", lambda: vol.astype(np.float16)),
            (TypeError, "holds complex128 values", lambda: vol.astype(complex)),
            (ValueError, "needs its spacing. Hint: give spacing=", lambda: vol, {"spacing": None}),
            (ValueError, "NaN or infinite voxel values", lambda: np.where(vol > 0, np.nan, 0.0)),
            (TypeError, "^threshold is str, not a number", lambda: vol, {"threshold": "half"}),
            (TypeError, "^iso is list, not a number", lambda: vol, {"iso": [0.5]}),
        ]
        for case in cases:
            error, message, make = case[:3]
            keywords = {"spacing": SPACING, **(case[3] if len(case) > 3 else {})}
            with self.subTest(message=message):
                with self.assertRaisesRegex(error, message) as caught:
                    scalemesh.mesh_image(make(), **keywords)
                self.assertIsNone(caught.exception.__cause__)
                self.assertIsNone(caught.exception.__context__)


class TestHostGmshSession(unittest.TestCase):
    def test_a_msh_input_leaves_the_host_session_alone(self):
        gmsh.initialize()
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            with tempfile.TemporaryDirectory() as scratch:
                path = os.path.join(scratch, "sphere.msh")
                gmsh.model.add("sphere")
                gmsh.model.occ.addSphere(0, 0, 0, 3)
                gmsh.model.occ.synchronize()
                gmsh.option.setNumber("Mesh.MeshSizeMax", 0.8)
                gmsh.model.mesh.generate(2)
                gmsh.write(path)
                gmsh.model.remove()
                gmsh.model.add("host")
                models = gmsh.model.list()
                result = scalemesh.mesh_image(path, gmsh_session=True, threads=2)
                self.assertGreater(len(result["tets"]), 0)
                # Gmsh still initialised, the host's model current, no model added.
                self.assertEqual(gmsh.model.getCurrent(), "host")
                self.assertEqual(gmsh.model.list(), models)
                self.assertEqual(gmsh.option.getNumber("Mesh.MeshSizeMax"), 0.8)
        finally:
            gmsh.finalize()
        with self.assertRaisesRegex(ValueError, "Gmsh has no model"):
            scalemesh.mesh_image(path, gmsh_session=True)


class TestReadmeExample(unittest.TestCase):
    def test_the_image_array_example_runs_as_written(self):
        readme = os.path.join(os.path.dirname(__file__), "..", "..", "README.md")
        with open(readme) as f:
            text = f.read()
        marker = text.index("<!-- example: image-array")
        start = text.index("```python\n", marker) + len("```python\n")
        code = text[start:text.index("```", start)]
        namespace = {}
        exec(compile(code, "README.md image-array example", "exec"), namespace)
        # The example asserts that the mesh runs along x; and each call meshed.
        for name in ("mesh", "labelled", "again"):
            self.assertGreater(len(namespace[name]["tets"]), 0, name)


class TestMeshSurfaceMeshio(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        image = scalemesh.mesh_image(ellipsoid(), spacing=SPACING, threads=2)
        cls.points = image["points"][: image["surface_points"]]
        cls.triangles = image["boundary_triangles"]
        cls.result = scalemesh.mesh_surface(cls.points, cls.triangles, threads=2)

    def test_a_meshio_mesh_meshes_as_its_arrays(self):
        mesh = meshio.Mesh(self.points, [("vertex", np.array([[0]])), ("line", np.array([[0, 1]])),
                                         ("triangle", self.triangles[:10]), ("triangle", self.triangles[10:])])
        for given in (mesh, (self.points, self.triangles)):
            with self.subTest(given=type(given).__name__):
                np.testing.assert_array_equal(scalemesh.mesh_surface(given, threads=2)["points"],
                                              self.result["points"])

    def test_a_meshio_mesh_without_only_triangles_is_refused(self):
        with self.assertRaisesRegex(ValueError, r'has no "triangle" cells \(it has tetra\)'):
            scalemesh.mesh_surface(meshio.Mesh(self.points, [("tetra", np.array([[0, 1, 2, 3]]))]))
        with self.assertRaisesRegex(ValueError, "has quad cells besides its triangles"):
            scalemesh.mesh_surface(meshio.Mesh(self.points, [("triangle", self.triangles),
                                                             ("quad", np.array([[0, 1, 2, 3]]))]))
        with self.assertRaisesRegex(ValueError, r"points are not an \(N, 3\) array"):
            scalemesh.mesh_surface(meshio.Mesh(self.points[:, :2], [("triangle", self.triangles)]))
        with self.assertRaisesRegex(TypeError, "got a meshio.Mesh and triangles"):
            scalemesh.mesh_surface(meshio.Mesh(self.points, [("triangle", self.triangles)]), self.triangles)
        with self.assertRaisesRegex(TypeError, "needs the triangles"):
            scalemesh.mesh_surface(self.points)

    def test_the_module_imports_and_meshes_without_meshio(self):
        # meshio made unimportable: the module imports, does not import it,
        # and meshes arrays.
        script = (
            "import sys\nsys.modules['meshio'] = None\nimport numpy as np, scalemesh\n"
            "assert sys.modules['meshio'] is None\n"
            "data = np.load(sys.argv[1])\n"
            "print(len(scalemesh.mesh_surface(data['points'], data['triangles'], threads=2)['points']))\n"
        )
        with tempfile.TemporaryDirectory() as scratch:
            arrays = os.path.join(scratch, "surface.npz")
            np.savez(arrays, points=self.points, triangles=self.triangles)
            run = subprocess.run([sys.executable, "-c", script, arrays], capture_output=True, text=True)
        self.assertEqual(run.returncode, 0, run.stderr)
        self.assertEqual(int(run.stdout), len(self.result["points"]))


if __name__ == "__main__":
    unittest.main()
