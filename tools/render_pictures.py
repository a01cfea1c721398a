#!/usr/bin/env python3
"""Renders the README's pictures of a layered mesh, headless.

Regenerate them, from the project root, with the command line built:

    /usr/bin/python3 tools/render_pictures.py build/src/cli/scalemesh

(`apt-get install xvfb python3-gmsh`.) Gmsh draws through its FLTK window:
the script runs itself again under `xvfb-run`, a virtual screen of 24-bit
colour, so it needs no display. The script meshes the shared
aorta surface (`../shared/data/vmtk_aorta_capped.stl`, as
`cases/aorta_surface`, here with three clip-plane openings so that it has
caps) with `scalemesh run` in a temporary directory, then loads its
`mesh.msh` into Gmsh and writes

    docs/images/aorta-cutaway.png   the volume mesh cut lengthwise
    docs/images/aorta-cap.png       the inlet's cap, the layers across it

Each tet is coloured by the `layer` view scalemesh writes into mesh.msh:
the wall layers 1 to floor(M/2) from the wall inwards, then the core. The cut
keeps whole tets (those whose centre lies behind the plane), so the cut face
shows the cells as they are. mesh.msh stores a layer prism as its three
tets, and so does the picture. The run uses one thread, so its mesh is the
same every time, and a rerun on one machine draws the same pixels (the PNG
files' bytes may still differ).
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile

import gmsh
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SURFACE = os.path.normpath(os.path.join(ROOT, "..", "shared", "data", "vmtk_aorta_capped.stl"))

# cases/aorta_surface with openings: the proximal end (y = 181 mm) and the two
# iliac arteries (y = 98 mm) cut by planes a few millimetres inside the
# surface's own flat ends.
OPENINGS = [  # name, type, point, normal, radius (mm)
    ("inlet", "inlet", (221.0, 175.0, 21.5), (0.0, 1.0, 0.0), 12.0),
    ("right_iliac", "outlet", (210.3, 106.0, 30.7), (0.0, -1.0, 0.0), 7.0),
    ("left_iliac", "outlet", (234.8, 106.0, 29.0), (0.0, -1.0, 0.0), 7.0),
]


def case_text(surface):
    text = f'[input]\nfile = "{surface}"\nunits = "mm"\n\n[volume]\nmin_dihedral_deg = 10\n'
    for name, kind, point, normal, radius in OPENINGS:
        text += (f'\n[[openings]]\nname = "{name}"\ntype = "{kind}"\npoint = [{", ".join(map(str, point))}]\n'
                 f'normal = [{", ".join(map(str, normal))}]\nradius = {radius}\n')
    return text


# Wall layers from the wall inwards (dark to light blue), then the core.
LAYER_COLOURS = [(31, 78, 160), (66, 133, 214), (139, 187, 240), (176, 214, 250), (206, 228, 252)]
CORE_COLOUR = (236, 190, 120)


def run_scalemesh(binary, directory):
    with open(os.path.join(directory, "scalemesh.toml"), "w") as f:
        f.write(case_text(SURFACE))
    subprocess.run([binary, "run", directory, "--threads", "1", "-q"], check=True)
    with open(os.path.join(directory, "report.json")) as f:
        layers = json.load(f)["layers"]["layermaking"]  # floor(M / 2), the layers the wall owes
    return os.path.join(directory, "mesh.msh"), layers


def read_mesh(path):
    """Node coordinates by tag, the tets (node tags) and each tet's layer."""
    gmsh.open(path)
    tags, coords, _ = gmsh.model.mesh.getNodes()
    points = np.zeros((int(tags.max()) + 1, 3))
    points[tags.astype(int)] = coords.reshape(-1, 3)
    types, element_tags, element_nodes = gmsh.model.mesh.getElements(3)
    tets = np.asarray(element_nodes[list(types).index(4)], dtype=int).reshape(-1, 4)
    tet_tags = np.asarray(element_tags[list(types).index(4)], dtype=int)
    layer = None
    for view in gmsh.view.getTags():
        if gmsh.option.getString(f"View[{gmsh.view.getIndex(view)}].Name") == "layer":
            _, data_tags, data, _, _ = gmsh.view.getModelData(view, 0)
            by_tag = dict(zip(np.asarray(data_tags, dtype=int), (d[0] for d in data)))
            layer = np.array([by_tag[t] for t in tet_tags], dtype=int)
    if layer is None:
        sys.exit(f"{path} has no `layer` view")
    for view in gmsh.view.getTags():  # the picture shows the mesh, not its views
        gmsh.view.remove(view)
    # The wall nodes: those of the physical surface "wall".
    wall = None
    for dim, group in gmsh.model.getPhysicalGroups(2):
        if gmsh.model.getPhysicalName(dim, group) == "wall":
            wall, _ = gmsh.model.mesh.getNodesForPhysicalGroup(dim, group)
    if wall is None:
        sys.exit(f"{path} has no physical surface named `wall`")
    return points, tets, layer, points[np.asarray(wall, dtype=int)]


def show(points, tets, layer, keep, layers_owed, directory):
    """Opens a mesh of the kept tets, one coloured volume per layer.

    The mesh goes through a file: opening it is what fits Gmsh's view to it."""
    gmsh.clear()
    gmsh.model.add("picture")
    used = np.unique(tets[keep])
    classes = [(l, LAYER_COLOURS[min(l, len(LAYER_COLOURS)) - 1]) for l in range(1, layers_owed + 1)]
    classes.append((layers_owed + 1, CORE_COLOUR))
    colours = {}
    for value, colour in classes:
        chosen = keep & ((layer == value) if value <= layers_owed else (layer > layers_owed))
        if not chosen.any():
            continue
        entity = gmsh.model.addDiscreteEntity(3)
        if not colours:  # every node on the first volume; the others' tets refer to them by tag
            gmsh.model.mesh.addNodes(3, entity, used, points[used].ravel())
        gmsh.model.mesh.addElementsByType(entity, 4, [], tets[chosen].ravel())
        colours[entity] = colour
    path = os.path.join(directory, "picture.msh")
    gmsh.write(path)
    gmsh.clear()
    gmsh.open(path)
    for entity, colour in colours.items():
        gmsh.model.setColor([(3, entity)], *colour)


def set_view(rotation, size, scale=1.0):
    # The window's width includes the menu, to the left of the graphics.
    gmsh.option.setNumber("General.GraphicsWidth", size[0] + gmsh.option.getNumber("General.MenuWidth"))
    gmsh.option.setNumber("General.GraphicsHeight", size[1])
    gmsh.option.setNumber("General.Trackball", 0)
    gmsh.option.setNumber("General.RotationX", rotation[0])
    gmsh.option.setNumber("General.RotationY", rotation[1])
    gmsh.option.setNumber("General.RotationZ", rotation[2])
    gmsh.option.setNumber("General.ScaleX", scale)
    gmsh.option.setNumber("General.ScaleY", scale)
    gmsh.option.setNumber("General.ScaleZ", scale)
    gmsh.option.setNumber("General.TranslationX", 0)
    gmsh.option.setNumber("General.TranslationY", 0)


def render(path):
    gmsh.graphics.draw()
    gmsh.write(path)  # a .png: what the window shows
    print(f"wrote {os.path.relpath(path)} ({os.path.getsize(path) // 1024} KB)")


def main():
    if os.environ.get("SCALEMESH_PICTURES_XVFB") != "1":
        # Gmsh draws in its FLTK window: give it a virtual screen of its own,
        # with 24-bit colour, whatever display there is or is not.
        os.environ["SCALEMESH_PICTURES_XVFB"] = "1"
        if shutil.which("xvfb-run") is None:
            sys.exit("render_pictures.py: xvfb-run is not installed (apt-get install xvfb)")
        command = ["xvfb-run", "-a", "-s", "-screen 0 1920x1200x24", sys.executable] + sys.argv
        os.execvp(command[0], command)
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("scalemesh", help="the scalemesh command line, e.g. build/src/cli/scalemesh")
    parser.add_argument("--out", default=os.path.join(ROOT, "docs", "images"), help="default docs/images")
    parser.add_argument("--keep", metavar="DIR", help="mesh in DIR and keep it (default: a temporary directory)")
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)

    with tempfile.TemporaryDirectory(prefix="scalemesh-pictures-") as temporary:
        directory = args.keep or temporary
        os.makedirs(directory, exist_ok=True)
        mesh, layers_owed = run_scalemesh(os.path.abspath(args.scalemesh), directory)

        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        points, tets, layer, wall = read_mesh(mesh)
        gmsh.fltk.initialize()
        for name, value in (("General.SmallAxes", 0), ("General.BackgroundGradient", 0),
                            ("General.DrawBoundingBoxes", 0), ("Mesh.VolumeFaces", 1),
                            ("Mesh.VolumeEdges", 1), ("Mesh.SurfaceFaces", 0), ("Mesh.SurfaceEdges", 0),
                            ("Mesh.Lines", 0), ("Mesh.Points", 0), ("Mesh.ColorCarousel", 1),
                            ("Mesh.Light", 1), ("Mesh.LineWidth", 1), ("General.Antialiasing", 1)):
            gmsh.option.setNumber(name, value)
        gmsh.option.setColor("General.Background", 255, 255, 255)
        gmsh.option.setColor("General.Foreground", 40, 40, 40)
        gmsh.option.setColor("General.Text", 40, 40, 40)
        gmsh.option.setColor("Mesh.Lines", 30, 30, 30)

        # The plane the vessel lies in: through the wall nodes' centre, normal
        # to their least spread; the tets behind it stay.
        centre = wall.mean(axis=0)
        normal = np.linalg.svd(wall - centre, full_matrices=False)[2][2]
        if normal[2] < 0:
            normal = -normal
        tet_centres = points[tets].mean(axis=1)
        behind = (tet_centres - centre) @ normal < 0

        show(points, tets, layer, behind, layers_owed, directory)
        set_view((0, 0, 90), (1400, 560), scale=2.3)
        render(os.path.join(args.out, "aorta-cutaway.png"))

        # The inlet: its cap at y = 175 mm (OPENINGS[0]), normal +y; the last 10 mm of the
        # vessel, seen from outside the cap.
        near_inlet = tet_centres[:, 1] > OPENINGS[0][2][1] - 10.0
        show(points, tets, layer, near_inlet, layers_owed, directory)
        set_view((65, 0, 20), (900, 700), scale=0.95)
        render(os.path.join(args.out, "aorta-cap.png"))
        gmsh.finalize()


if __name__ == "__main__":
    main()
