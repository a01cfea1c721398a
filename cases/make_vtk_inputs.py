#!/usr/bin/python3
"""Writes the sample inputs of the VTK XML and open-surface cases.

  cases/bifurcation_vtp/bifurcation.vtp  closed three-branch bifurcation as
      VTK XML PolyData the way VMTK/SimVascular write it: appended raw data,
      zlib-compressed, UInt64 headers; cell array ModelFaceID 1 on the wall,
      2, 3, 4 on the planar end caps (parent, +x branch, -x branch)
  cases/bifurcation_open/bifurcation_open.stl  the same without its caps
      (binary STL, 3 boundary loops)
  cases/tube_open/tube_open.stl  a cylinder of radius 2 mm and length 20 mm
      without its caps (binary STL, 2 boundary loops)

Geometry from Gmsh's OpenCASCADE kernel, meshed in 2D at about 0.8 mm;
everything else with the standard library (struct, zlib). Lengths in mm.
Run with /usr/bin/python3 (which has gmsh) from anywhere; it overwrites the
files above and prints what it wrote.
"""

import math
import os
import struct
import zlib

import gmsh

HERE = os.path.dirname(os.path.abspath(__file__))
MESH_SIZE = 0.8  # mm


def mesh_surfaces(build):
    """Meshes the OCC volume `build()` makes; returns points, and per
    boundary surface its triangles oriented outwards and whether it is a
    plane, and its centre of mass."""
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("m")
    build()
    gmsh.model.occ.synchronize()
    gmsh.option.setNumber("Mesh.MeshSizeMin", MESH_SIZE)
    gmsh.option.setNumber("Mesh.MeshSizeMax", MESH_SIZE)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.model.mesh.generate(2)
    volumes = gmsh.model.getEntities(3)
    assert len(volumes) == 1, volumes
    tags, coords, _ = gmsh.model.mesh.getNodes()
    xyz = {int(t): (coords[3 * i], coords[3 * i + 1], coords[3 * i + 2]) for i, t in enumerate(tags)}
    surfaces = []
    for dim, signed in gmsh.model.getBoundary(volumes, oriented=True):
        tag = abs(signed)
        types, _, nodes = gmsh.model.mesh.getElements(2, tag)
        triangles = []
        for etype, enodes in zip(types, nodes):
            assert etype == 2, "only 3-node triangles expected"
            for i in range(0, len(enodes), 3):
                t = (int(enodes[i]), int(enodes[i + 1]), int(enodes[i + 2]))
                triangles.append(t if signed > 0 else (t[0], t[2], t[1]))
        plane = gmsh.model.getType(2, tag) == "Plane"
        centre = gmsh.model.occ.getCenterOfMass(2, tag)
        surfaces.append((triangles, plane, centre))
    gmsh.finalize()
    return xyz, surfaces


def compact(xyz, triangles):
    """Points used by `triangles`, numbered by first use, and the triangles
    renumbered."""
    index, points, out = {}, [], []
    for t in triangles:
        row = []
        for n in t:
            if n not in index:
                index[n] = len(points)
                points.append(xyz[n])
            row.append(index[n])
        out.append(tuple(row))
    return points, out


def signed_volume(points, triangles):
    v = 0.0
    for a, b, c in triangles:
        (ax, ay, az), (bx, by, bz), (cx, cy, cz) = points[a], points[b], points[c]
        v += ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)
    return v / 6.0


def boundary_loops(triangles):
    """Number of closed loops of edges used by one triangle only."""
    count = {}
    for t in triangles:
        for i in range(3):
            e = tuple(sorted((t[i], t[(i + 1) % 3])))
            count[e] = count.get(e, 0) + 1
    edges = [e for e, n in count.items() if n == 1]
    parent = {}

    def find(a):
        while parent.setdefault(a, a) != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for a, b in edges:
        parent[find(a)] = find(b)
    return len({find(a) for e in edges for a in e})


def write_stl(path, points, triangles, scale=1.0):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "wb") as f:
        f.write(b"scalemesh cases/make_vtk_inputs.py".ljust(80, b" "))
        f.write(struct.pack("<I", len(triangles)))
        for t in triangles:
            p = [[c * scale for c in points[n]] for n in t]
            u = [p[1][k] - p[0][k] for k in range(3)]
            v = [p[2][k] - p[0][k] for k in range(3)]
            n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
            length = math.sqrt(sum(c * c for c in n)) or 1.0
            f.write(struct.pack("<3f", *(c / length for c in n)))
            for q in p:
                f.write(struct.pack("<3f", *q))
            f.write(b"\0\0")
    print(f"{os.path.relpath(path, HERE)}: {len(triangles)} triangles, {boundary_loops(triangles)} boundary loops, "
          f"{os.path.getsize(path)} bytes")


def appended_zlib(data, block=32768):
    """VTK's compressed layout with UInt64 header words: [blocks, block size,
    last block size (0: whole), compressed sizes...][zlib blocks]."""
    blocks = [zlib.compress(data[i:i + block]) for i in range(0, len(data), block)]
    header = [len(blocks), block, len(data) % block] + [len(b) for b in blocks]
    return struct.pack(f"<{len(header)}Q", *header) + b"".join(blocks)


def write_vtp(path, points, triangles, labels):
    arrays = [
        ("CellData", "Int32", "ModelFaceID", 1, struct.pack(f"<{len(labels)}i", *labels)),
        ("Points", "Float64", "Points", 3, struct.pack(f"<{3 * len(points)}d", *(c for p in points for c in p))),
        ("Polys", "Int64", "connectivity", 1, struct.pack(f"<{3 * len(triangles)}q", *(n for t in triangles for n in t))),
        ("Polys", "Int64", "offsets", 1, struct.pack(f"<{len(triangles)}q", *range(3, 3 * len(triangles) + 1, 3))),
    ]
    appended, xml = b"", {}
    for parent, vtype, name, components, data in arrays:
        xml.setdefault(parent, "")
        xml[parent] += (f'        <DataArray type="{vtype}" Name="{name}" NumberOfComponents="{components}" '
                        f'format="appended" offset="{len(appended)}"/>\n')
        appended += appended_zlib(data)
    head = (
        '<?xml version="1.0"?>\n'
        '<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian" header_type="UInt64" '
        'compressor="vtkZLibDataCompressor">\n'
        '  <PolyData>\n'
        f'    <Piece NumberOfPoints="{len(points)}" NumberOfVerts="0" NumberOfLines="0" NumberOfStrips="0" '
        f'NumberOfPolys="{len(triangles)}">\n'
        '      <PointData>\n      </PointData>\n'
        f'      <CellData Scalars="ModelFaceID">\n{xml["CellData"]}      </CellData>\n'
        f'      <Points>\n{xml["Points"]}      </Points>\n'
        f'      <Polys>\n{xml["Polys"]}      </Polys>\n'
        '    </Piece>\n  </PolyData>\n  <AppendedData encoding="raw">\n   _'
    )
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "wb") as f:
        f.write(head.encode() + appended + b"\n  </AppendedData>\n</VTKFile>\n")
    print(f"{os.path.relpath(path, HERE)}: {len(triangles)} triangles, labels {sorted(set(labels))}, "
          f"{os.path.getsize(path)} bytes")


# Parent along +z ending at the origin, a ball there to round the junction
# and cover the branches' base disks, two branches at +-30 degrees from z.
PARENT_R, PARENT_L = 3.0, 20.0
BRANCH_R, BRANCH_L, BRANCH_ANGLE = 2.2, 18.0, math.radians(30)


def bifurcation():
    occ = gmsh.model.occ
    parent = occ.addCylinder(0, 0, -PARENT_L, 0, 0, PARENT_L, PARENT_R)
    ball = occ.addSphere(0, 0, 0, PARENT_R)
    s, c = math.sin(BRANCH_ANGLE), math.cos(BRANCH_ANGLE)
    right = occ.addCylinder(0, 0, 0, BRANCH_L * s, 0, BRANCH_L * c, BRANCH_R)
    left = occ.addCylinder(0, 0, 0, -BRANCH_L * s, 0, BRANCH_L * c, BRANCH_R)
    occ.fuse([(3, parent)], [(3, ball), (3, right), (3, left)])


def bifurcation_cap(centre):
    """ModelFaceID of a planar end cap by where its centre lies."""
    s, c = math.sin(BRANCH_ANGLE), math.cos(BRANCH_ANGLE)
    ends = {2: (0, 0, -PARENT_L), 3: (BRANCH_L * s, 0, BRANCH_L * c), 4: (-BRANCH_L * s, 0, BRANCH_L * c)}
    for label, end in ends.items():
        if math.dist(centre, end) < 1e-6:
            return label
    raise RuntimeError(f"a planar face at {centre} is no end cap")


def tube():
    gmsh.model.occ.addCylinder(0, 0, 0, 0, 0, 20.0, 2.0)


def main():
    xyz, surfaces = mesh_surfaces(bifurcation)
    triangles, labels, wall = [], [], []
    for tris, plane, centre in surfaces:
        label = bifurcation_cap(centre) if plane else 1
        triangles += tris
        labels += [label] * len(tris)
        if not plane:
            wall += tris
    assert sorted(set(labels)) == [1, 2, 3, 4], sorted(set(labels))
    points, closed = compact(xyz, triangles)
    assert boundary_loops(closed) == 0 and signed_volume(points, closed) > 0
    write_vtp(os.path.join(HERE, "bifurcation_vtp", "bifurcation.vtp"), points, closed, labels)
    points, open_wall = compact(xyz, wall)
    assert boundary_loops(open_wall) == 3
    write_stl(os.path.join(HERE, "bifurcation_open", "bifurcation_open.stl"), points, open_wall)

    xyz, surfaces = mesh_surfaces(tube)
    wall = [t for tris, plane, _ in surfaces if not plane for t in tris]
    assert sum(1 for _, plane, _ in surfaces if plane) == 2
    points, open_wall = compact(xyz, wall)
    assert boundary_loops(open_wall) == 2
    write_stl(os.path.join(HERE, "tube_open", "tube_open.stl"), points, open_wall)


if __name__ == "__main__":
    main()
