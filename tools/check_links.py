#!/usr/bin/env python3
"""Every target links what it includes.

For each target of the project's CMakeLists.txt files (add_library,
add_executable, scalemesh_test, scalemesh_fuzzer), the project headers its
sources include ("dir/name.h"), each owned by the target that compiles the
.cpp of the same name (else by the one target of its folder), are checked
against what it links: directly, or through a PUBLIC (INTERFACE) link of a
target it links. Prints one line per include of a target not linked and
exits 1 when there is any; --graph prints each target's project links and
the targets it includes from.

    python3 tools/check_links.py [--graph] [--all]

Without --all only the stage libraries are checked (src/, importers/,
exporters/, gmsh_io/), not tests, benchmarks or fuzzers.
"""
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
STAGE_DIRS = ("src", "importers", "exporters", "gmsh_io")
SKIP_DIRS = {"build", ".git", "cases", "docs"}
VISIBILITY = {"PUBLIC", "PRIVATE", "INTERFACE"}
# include/scalemesh/: the library's public headers, on the include path of
# the targets that compile the library (src/api/), of those linking it, and
# of those linking scalemesh_headers (the headers alone, for the pipeline).
PUBLIC_HEADERS = "scalemesh (include/)"
PUBLIC_HEADER_TARGETS = {"scalemesh_api", "scalemesh_library", "scalemesh_static", "scalemesh_headers"}


def cmake_commands(path):
    """The commands of one CMakeLists.txt, with the lists it set() expanded."""
    text = "\n".join(line.split("#", 1)[0] if not line.lstrip().startswith("#") else ""
                     for line in open(path, encoding="utf-8"))
    variables = {}
    for name, args in re.findall(r"\b(\w+)\s*\(([^()]*)\)", text):
        words = []
        for a in args.split():
            a = a.strip("\"")
            m = re.fullmatch(r"\$\{(\w+)\}", a)
            words += variables.get(m.group(1), []) if m else [a]
        if name.lower() == "set" and words:
            variables[words[0]] = words[1:]
        yield name.lower(), words


def read_targets():
    targets = {}  # name -> {"dir", "sources": [paths], "links": [(target, public)]}
    aliases = {}
    for folder, dirs, files in os.walk(ROOT):
        dirs[:] = [d for d in dirs if d not in SKIP_DIRS and not d.startswith(".")]
        if "CMakeLists.txt" not in files:
            continue
        for cmd, args in cmake_commands(os.path.join(folder, "CMakeLists.txt")):
            if not args:
                continue
            if cmd in ("add_library", "add_executable", "pybind11_add_module"):
                name = args[0]
                if len(args) == 3 and args[1] == "ALIAS":
                    aliases[name] = args[2]
                    continue
                sources = [a for a in args[1:] if a.endswith(".cpp")]
                targets[name] = {"dir": folder, "sources": [os.path.join(folder, s) for s in sources], "links": []}
            elif cmd == "target_sources" and args[0] in targets:
                targets[args[0]]["sources"] += [os.path.join(folder, a) for a in args[1:] if a.endswith(".cpp")]
            elif cmd == "target_link_libraries" and args[0] in targets:
                public = False  # plain signature: treated as private
                for a in args[1:]:
                    if a in VISIBILITY:
                        public = a != "PRIVATE"
                    else:
                        targets[args[0]]["links"].append((a, public))
            elif cmd in ("scalemesh_test", "scalemesh_fuzzer"):
                name = args[0] if cmd == "scalemesh_test" else "fuzz_" + args[0]
                section, sources, links = None, [], []
                for a in args[1:]:
                    if a in ("SOURCES", "LIBS", "FAST", "USES_BINARY", "REPLAY_ONLY"):
                        section = a
                    elif section == "SOURCES":
                        sources.append(os.path.join(folder, a))
                    elif section == "LIBS":
                        links.append((a, False))
                targets[name] = {"dir": folder, "sources": sources, "links": links}
    for t in targets.values():
        t["links"] = [(aliases.get(l, l), public) for l, public in t["links"]]
    return targets


def header_owners(targets):
    by_cpp = {}
    by_dir = {}
    for name, t in targets.items():
        for s in t["sources"]:
            by_cpp[os.path.splitext(s)[0]] = name
            by_dir.setdefault(os.path.dirname(s), set()).add(name)
    owners = {}

    def owner(header):
        if header in owners:
            return owners[header]
        result = None
        if header.startswith("scalemesh/"):
            result = PUBLIC_HEADERS
        else:
            for base in (os.path.join(ROOT, "src"), ROOT):
                path = os.path.join(base, header)
                if os.path.exists(path) or (header == "core/version.h" and base.endswith("src")):
                    stem = os.path.splitext(path)[0]
                    if stem in by_cpp:
                        result = by_cpp[stem]
                    else:
                        libs = [n for n in by_dir.get(os.path.dirname(path), ()) if not n.startswith("test")]
                        result = libs[0] if len(libs) == 1 else None
                    break
        owners[header] = result
        return result

    return owner


def include_name(path):
    """How a header is included: relative to src/, else to the top."""
    src = os.path.join(ROOT, "src")
    return os.path.relpath(path, src if path.startswith(src + os.sep) else ROOT)


def closure(targets, name):
    """The targets whose usage requirements `name` gets: its links, and their public links, transitively."""
    seen = set()
    stack = [l for l, _ in targets[name]["links"] if l in targets]
    while stack:
        l = stack.pop()
        if l in seen:
            continue
        seen.add(l)
        stack += [m for m, public in targets[l]["links"] if public and m in targets]
    return seen


def includes(path):
    try:
        text = open(path, encoding="utf-8").read()
    except OSError:
        return []
    return re.findall(r'^\s*#\s*include\s+"([^"]+)"', text, re.M)


def main():
    graph = "--graph" in sys.argv
    check_all = "--all" in sys.argv
    targets = read_targets()
    owner = header_owners(targets)
    problems = 0
    for name in sorted(targets):
        t = targets[name]
        rel = os.path.relpath(t["dir"], ROOT)
        if not check_all and not rel.startswith(STAGE_DIRS):
            continue
        # Its sources and its own headers (compiled into its sources and its users').
        files = list(t["sources"])
        files += [os.path.join(t["dir"], f) for f in os.listdir(t["dir"])
                  if f.endswith(".h") and owner(include_name(os.path.join(t["dir"], f))) == name]
        linked = closure(targets, name)
        if name in PUBLIC_HEADER_TARGETS or linked & PUBLIC_HEADER_TARGETS:
            linked.add(PUBLIC_HEADERS)
        used = {}
        for f in sorted(set(files)):
            for h in includes(f):
                o = owner(h)
                if o is None or o == name or any(s.endswith("/" + os.path.splitext(h)[0] + ".cpp")
                                                 for s in t["sources"]):
                    continue
                used.setdefault(o, []).append((os.path.relpath(f, ROOT), h))
        if graph:
            direct = [l for l, _ in t["links"] if l in targets]
            print(f"{name}: links {' '.join(direct) or '-'}; includes from {' '.join(sorted(used)) or '-'}")
        for o, where in sorted(used.items()):
            if o not in linked:
                problems += 1
                for f, h in where:
                    print(f"{name}: {f} includes {h} of {o}, not linked")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
