#!/usr/bin/python3
"""scalemesh in the Gmsh GUI, as a ONELAB client.

Open this file in Gmsh (`gmsh scalemesh_gui.py`, or File > Open): Gmsh runs it
as a ONELAB client and shows its parameters in the left panel (the input
surface or image, M, K, L_min, L_max, G, growth, and for a .msh input one
choice per physical surface: automatic, inlet or outlet). The options'
defaults, ranges and help are scalemesh's own, read from
`scalemesh options --json`. *Run* writes a case
directory with a `scalemesh.toml`, runs the `scalemesh` command line on it and
merges the `mesh.msh` it writes into the GUI: the tetrahedra, the physical
groups (fluid, wall, one per opening) and the views (D, D_out, d, ...).
Messages from scalemesh go to Gmsh's message console; a failed run is shown
as an error there and nothing is merged.

The scalemesh binary is the one named by the parameter Run > scalemesh binary,
else $SCALEMESH_BINARY, else bin/scalemesh of the prefix this script is
installed under (share/scalemesh/), else `scalemesh` on PATH.

Gmsh 4.8 (Debian 12) starts the client with `-onelab NAME SOCKET`. Its Python
API connects when given those arguments, but its gmsh.onelab functions then
read and write the client's own local database, not the GUI's, so this file
speaks the ONELAB socket protocol itself (the message types and parameter
layout of version 1.3 of Gmsh's onelab.h, MIT licensed, as its onelab.py
client does). The python gmsh module (python3-gmsh) is used only to list the
physical surfaces of a .msh input.

Test hook: with SCALEMESH_GUI_SAVE=PREFIX in the environment, after merging,
Gmsh is asked to save the model it now holds as PREFIX.msh and each view as
PREFIX_view<i>.pos (tests/gui/).
"""

import json
import os
import re
import shutil
import socket
import struct
import subprocess
import sys
import tempfile

# Message types of Gmsh's GmshSocket.h.
_START = 1
_STOP = 2
_INFO = 10
_WARNING = 11
_ERROR = 12
_PROGRESS = 13
_PARSE_STRING = 21
_PARAMETER = 23
_PARAMETER_QUERY = 24
_PARAMETER_NOT_FOUND = 29

_PROTOCOL_VERSION = "1.3"
# Field layout of a serialised parameter (onelab.h, parameter::toChar): the
# common fields, then those of the type.
_COMMON_FIELDS = [("name", "str"), ("label", "str"), ("help", "str"), ("changed", "int"),
                  ("visible", "int"), ("readOnly", "int"), ("attributes", "dict_str_str"),
                  ("clients", "dict_str_int")]
_TYPE_FIELDS = {
    "number": [("values", "list_float"), ("min", "float"), ("max", "float"), ("step", "float"),
               ("index", "int"), ("choices", "list_float"), ("valueLabels", "dict_float_str")],
    "string": [("values", "list_str"), ("kind", "str"), ("choices", "list_str")],
}
_DEFAULTS = {"str": "", "int": 0, "float": 0.0, "list_float": [], "list_str": [], "dict_str_str": {},
             "dict_str_int": {}, "dict_float_str": {}}


def _new_parameter(ptype, name, **fields):
    p = {"type": ptype}
    for key, kind in _COMMON_FIELDS + _TYPE_FIELDS[ptype]:
        p[key] = type(_DEFAULTS[kind])(_DEFAULTS[kind])
    p["name"] = name
    # onelab.h's defaults: changed for every client, visible, an open range.
    p.update(changed=31, visible=1)
    p.update({"min": -1e200, "max": 1e200, "index": -1} if ptype == "number" else {"kind": "generic"})
    p.update(fields)
    return p


def _serialise(p):
    out = [_PROTOCOL_VERSION, p["type"]]

    def put(kind, value):
        if kind == "str":
            out.append(value)
        elif kind == "int":
            out.append(str(int(value)))
        elif kind == "float":
            out.append("%.16g" % value)
        elif kind.startswith("list_"):
            out.append(str(len(value)))
            for v in value:
                put(kind[5:], v)
        else:  # dict_<key>_<value>
            _, key_kind, value_kind = kind.split("_")
            out.append(str(len(value)))
            for k, v in value.items():
                put(key_kind, k)
                put(value_kind, v)

    for key, kind in _COMMON_FIELDS + _TYPE_FIELDS[p["type"]]:
        put(kind, p[key])
    return "\0".join(out) + "\0"


def _parse(message):
    items = message.split("\0")
    items.reverse()

    def take(kind):
        if kind == "str":
            return items.pop()
        if kind == "int":
            return int(items.pop())
        if kind == "float":
            return float(items.pop())
        if kind.startswith("list_"):
            return [take(kind[5:]) for _ in range(int(items.pop()))]
        _, key_kind, value_kind = kind.split("_")
        return dict((take(key_kind), take(value_kind)) for _ in range(int(items.pop())))

    version, ptype = items.pop(), items.pop()
    if version != _PROTOCOL_VERSION or ptype not in _TYPE_FIELDS:
        raise RuntimeError("ONELAB parameter of version %s, type %s: this client speaks version %s"
                           % (version, ptype, _PROTOCOL_VERSION))
    p = {"type": ptype}
    for key, kind in _COMMON_FIELDS + _TYPE_FIELDS[ptype]:
        p[key] = take(kind)
    return p


class OnelabClient:
    """The client end of a Gmsh ONELAB socket (`-onelab NAME SOCKET`)."""

    def __init__(self, name, address):
        self.name = name
        if ":" in address and "/" not in address:
            host, port = address.rsplit(":", 1)
            self._socket = socket.create_connection((host, int(port)))
        else:
            self._socket = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            self._socket.connect(address)
        self._send(_START, str(os.getpid()))

    def _send(self, mtype, text):
        body = text.encode("utf-8")
        self._socket.sendall(struct.pack("ii", mtype, len(body)) + body)

    def _receive_exactly(self, size):
        data = b""
        while len(data) < size:
            chunk = self._socket.recv(size - len(data))
            if not chunk:
                raise RuntimeError("Gmsh closed the ONELAB connection")
            data += chunk
        return data

    def _receive(self):
        mtype, size = struct.unpack("ii", self._receive_exactly(8))
        return mtype, self._receive_exactly(size).decode("utf-8")

    def get(self, ptype, name):
        """The parameter as the server holds it, or None."""
        self._send(_PARAMETER_QUERY, _serialise(_new_parameter(ptype, name)))
        mtype, message = self._receive()
        return _parse(message) if mtype == _PARAMETER else None

    def set(self, p):
        self._send(_PARAMETER, _serialise(p))

    def define(self, ptype, name, default, **fields):
        """ONELAB's define: create the parameter with `default` when the server
        does not hold it, else keep the server's value (the user's) and refresh
        the label, range, choices and flags. Returns the value."""
        held = self.get(ptype, name)
        p = _new_parameter(ptype, name, **fields)
        p["values"] = held["values"] if held and held["values"] else [default]
        if held:
            p["clients"] = held["clients"]
        if fields.get("readOnly"):
            p["values"] = [default]
        self.set(p)
        return p["values"][0]

    def action(self):
        p = self.get("string", self.name + "/Action")
        return p["values"][0] if p and p["values"] else ""

    def info(self, text):
        self._send(_INFO, text)

    def warning(self, text):
        self._send(_WARNING, text)

    def error(self, text):
        self._send(_ERROR, text)

    def progress(self, text):
        self._send(_PROGRESS, text)

    def parse(self, geo_commands):
        """Have Gmsh run .geo commands in its current model."""
        self._send(_PARSE_STRING, geo_commands)

    def close(self):
        self._send(_STOP, "Goodbye")
        self._socket.close()


ROOT = "scalemesh/"
OPENING_CHOICES = {0: "automatic", 1: "inlet", 2: "outlet"}


def physical_surfaces(path):
    """(tag, name) of the named physical surfaces of a .msh: the face labels
    scalemesh reads from it (docs/case-file.md, Open ends and labelled caps)."""
    import gmsh  # python3-gmsh

    gmsh.initialize([], False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(path)
        return [(tag, gmsh.model.getPhysicalName(2, tag)) for _, tag in gmsh.model.getPhysicalGroups(2)
                if gmsh.model.getPhysicalName(2, tag)]
    finally:
        gmsh.finalize()


def patch_name(name, tag):
    """A patch name scalemesh accepts: letters, digits and _, not starting with
    a digit, not `wall`."""
    cleaned = re.sub(r"[^A-Za-z0-9_]", "_", name)
    if not cleaned or cleaned[0].isdigit() or cleaned == "wall":
        cleaned = "cap_%d" % tag
    return cleaned


def option_table(binary):
    """The meshing options as `scalemesh options --json` lists them (section,
    key, kind, default, min, max, choices, unit, doc), by Python keyword: the
    defaults, ranges and help shown here are scalemesh's own."""
    listed = subprocess.run([binary, "options", "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            universal_newlines=True)
    if listed.returncode != 0:
        raise RuntimeError("%s options --json failed (exit code %d): %s"
                           % (binary, listed.returncode, listed.stderr.strip()))
    return {o["keyword"]: o for o in json.loads(listed.stdout)}


# The options shown in the GUI: (keyword, parameter name, slider step).
GUI_OPTIONS = [("M", "1Sizing/1M", 1), ("K", "1Sizing/2K", 0.1), ("L_min", "1Sizing/3L_min (mm)", 0.1),
               ("L_max", "1Sizing/4L_max (mm)", 1), ("G", "1Sizing/5G", 0.05), ("growth", "2Volume/growth", 0.05)]
# A length is given here in mm, 0 meaning scalemesh's default; its slider
# ends at this many mm (scalemesh bounds a length only below, by 0).
LENGTH_SLIDER_MAX = 1000


def define_option(client, option, name, step):
    """One option of the table as a number parameter, with its default, range and doc."""
    help_text = option["doc"]
    if option["unit"]:
        help_text += " (%s)" % option["unit"]
    if option["kind"] == "length":
        default = option["default"]
        help_text += "; 0: the default, %s" % ("unset" if default is None else
                                               default if isinstance(default, str) else "%g mm" % default)
        return client.define("number", ROOT + name, 0, min=0, max=LENGTH_SLIDER_MAX, step=step, help=help_text)
    interval = "%s%g, %g]" % ("(" if option["min_open"] else "[", option["min"], option["max"])
    # An open lower end is not a value: the slider starts a step above it.
    low = option["min"] + step if option["min_open"] else option["min"]
    return client.define("number", ROOT + name, option["default"], min=low, max=option["max"], step=step,
                         help="%s, in %s" % (help_text, interval))


def define_parameters(client):
    """Every parameter shown in the GUI, with the user's current values."""
    values = {
        "input": client.define("string", ROOT + "0Input file", "", kind="file",
                               help="surface (.stl .ply .obj .vtp .msh) or image (.vdb .nii .nii.gz .nrrd .mha)"),
        "binary": client.define("string", ROOT + "4Run/scalemesh binary", "",
                                help="empty: $SCALEMESH_BINARY, the installed bin/scalemesh, or scalemesh on PATH"),
        "case": client.define("string", ROOT + "4Run/Case directory", "",
                              help="empty: <input>_scalemesh next to the input (a temporary directory if "
                                   "that is not writable)"),
        "openings": [],
    }
    # Without a scalemesh to list the options, the other parameters are
    # still defined (the binary can be chosen, the openings listed), the
    # reason shown once; Run says it again.
    try:
        values["options"] = option_table(find_binary(values))
    except (RuntimeError, OSError, ValueError) as e:
        values["options"] = None
        values["options_error"] = str(e)
        client.error(str(e))
    for keyword, name, step in GUI_OPTIONS if values["options"] else []:
        values[keyword] = define_option(client, values["options"][keyword], name, step)
    path = values["input"]
    if path.lower().endswith(".msh") and os.path.isfile(path):
        try:
            surfaces = physical_surfaces(path)
        except ImportError:
            client.warning("python3-gmsh is not installed: the physical surfaces of '%s' are not listed; "
                           "scalemesh still finds its flat labelled caps" % path)
            surfaces = []
        for tag, name in surfaces:
            choice = client.define("number", ROOT + "3Openings/%s (%d)" % (name, tag), 0,
                                   choices=list(OPENING_CHOICES), valueLabels={float(k): v for k, v in
                                                                                OPENING_CHOICES.items()},
                                   help="automatic: a flat cap becomes an outlet named after it, the rest wall")
            if int(choice) in (1, 2):
                values["openings"].append((patch_name(name, tag), OPENING_CHOICES[int(choice)], tag))
    values["openings"].sort(key=lambda o: o[1] != "inlet")  # patches are numbered in the case file's order
    return values


def toml_string(text):
    return json.dumps(text)  # a JSON string is a TOML basic string


def case_file(values):
    lines = ["# Written by scalemesh_gui.py from the Gmsh GUI's parameters.",
             "[input]", "file = %s" % toml_string(os.path.abspath(values["input"]))]
    sections = {}
    for keyword, _, _ in GUI_OPTIONS:
        option = values["options"][keyword]
        if option["kind"] == "length" and values[keyword] <= 0:
            continue  # scalemesh's default
        sections.setdefault(option["section"], []).append("%s = %.16g" % (option["key"], values[keyword]))
    for section, keys in sections.items():
        lines += ["", "[%s]" % section] + keys
    for name, otype, tag in values["openings"]:
        lines += ["", "[[openings]]", "name = %s" % toml_string(name), "type = %s" % toml_string(otype),
                  "label = %d" % tag]
    return "\n".join(lines) + "\n"


def case_directory(values):
    if values["case"]:
        return os.path.abspath(values["case"])
    stem = os.path.basename(values["input"])
    for ext in (".nii.gz", ".stl", ".ply", ".obj", ".vtp", ".msh", ".vdb", ".nii", ".nrrd", ".nhdr", ".mha",
                ".mhd"):
        if stem.lower().endswith(ext):
            stem = stem[: -len(ext)]
            break
    beside = os.path.join(os.path.dirname(os.path.abspath(values["input"])), stem + "_scalemesh")
    try:
        os.makedirs(beside, exist_ok=True)
        probe = tempfile.NamedTemporaryFile(dir=beside)
        probe.close()
        return beside
    except OSError:
        return tempfile.mkdtemp(prefix=stem + "_scalemesh_")


def find_binary(values):
    candidates = [values["binary"], os.environ.get("SCALEMESH_BINARY", "")]
    here = os.path.dirname(os.path.realpath(__file__))
    candidates.append(os.path.join(here, "..", "..", "bin", "scalemesh"))  # PREFIX/share/scalemesh/
    candidates.append(shutil.which("scalemesh") or "")
    for c in candidates:
        if c and os.path.isfile(c) and os.access(c, os.X_OK):
            return os.path.abspath(c)
    raise RuntimeError("cannot find the scalemesh program: set Run > scalemesh binary, or SCALEMESH_BINARY, "
                       "or put scalemesh on PATH")


def geo_string(text):
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def run_scalemesh(client, values):
    if not values["input"]:
        raise RuntimeError("no input file: choose one under scalemesh > Input file")
    if not os.path.isfile(values["input"]):
        raise RuntimeError("the input file '%s' does not exist: choose another under scalemesh > Input file"
                           % values["input"])
    if values["options"] is None:
        raise RuntimeError(values["options_error"])
    binary = find_binary(values)
    case = case_directory(values)
    with open(os.path.join(case, "scalemesh.toml"), "w") as f:
        f.write(case_file(values))
    client.info("running %s run %s" % (binary, case))
    process = subprocess.Popen([binary, "run", case], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                               universal_newlines=True)
    tail = []
    for line in process.stdout:
        line = line.rstrip("\n")
        tail = (tail + [line])[-5:]
        if "warning:" in line:
            client.warning(line)
        else:
            client.info(line)
        if line.startswith("scalemesh: ") and "error" not in line:
            client.progress(line[len("scalemesh: "):].split("  ")[0])
    if process.wait() != 0:
        errors = [l for l in tail if "error" in l] or tail
        raise RuntimeError("scalemesh failed (exit code %d): %s" % (process.returncode, " / ".join(errors)))

    mesh = os.path.join(case, "mesh.msh")
    if not os.path.isfile(mesh):
        raise RuntimeError("scalemesh wrote no mesh.msh into %s: ask for it in [output] volume" % case)
    report = json.load(open(os.path.join(case, "report.json")))
    client.define("string", ROOT + "5Result/Case directory", case, readOnly=1, kind="generic")
    client.define("number", ROOT + "5Result/Tetrahedra", report["volume"]["tets"], readOnly=1)
    client.define("number", ROOT + "5Result/Worst aspect ratio",
                  report["volume"]["quality_after_sliver_removal"]["min_aspect_ratio"], readOnly=1)
    client.define("number", ROOT + "5Result/Layer coverage", report["layers"]["coverage"], readOnly=1)

    # The project's model holds only the previous run's mesh and views: drop
    # them (the views first, they refer to the mesh), then merge the new mesh
    # into the current model, so that File > Save, the physical groups and
    # Tools > Visibility see it.
    commands = ["For i In {PostProcessing.NbViews-1:0:-1}", "  Delete View[i];", "EndFor", "Delete Model;",
                "Merge %s;" % geo_string(mesh)]
    save = os.environ.get("SCALEMESH_GUI_SAVE")
    if save:
        commands += ["Save %s;" % geo_string(save + ".msh"),
                     "For i In {0:PostProcessing.NbViews-1}",
                     "  Save View[i] Sprintf(%s, i);" % geo_string(save.replace("%", "%%") + "_view%g.pos"),
                     "EndFor"]
    client.parse("\n".join(commands) + "\n")
    client.info("merged %s" % mesh)


def main(argv):
    if "-onelab" not in argv or argv.index("-onelab") + 2 >= len(argv):
        sys.stderr.write("scalemesh_gui.py is a ONELAB client of the Gmsh GUI: open it in Gmsh "
                         "(gmsh %s)\n" % argv[0])
        return 2
    i = argv.index("-onelab")
    client = OnelabClient(argv[i + 1], argv[i + 2])
    try:
        action = client.action()
        if action != "initialize":
            values = define_parameters(client)
            if action == "compute":
                run_scalemesh(client, values)
    except Exception as e:  # shown in Gmsh's message console, not lost on a pipe
        client.error(str(e))
    finally:
        client.close()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
