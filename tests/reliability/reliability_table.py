#!/usr/bin/env python3
"""Regenerates the fuzzing and hostile-input tables of docs/reliability.md.

From the project root:

    python3 tests/reliability/reliability_table.py [--seconds 60]

1. builds test_reliability (build/) and the fuzzers (build-fuzz/), one after
   the other with -j2 (--no-build skips this);
2. runs the HostileInput tests with --gtest_output=json and reads each test's
   result and its recorded properties "input" and "outcome" (RecordedOutcome in
   hostile_support.h: what the test's own runs did);
3. makes the seed corpus (ctest -R fuzz_seeds) and runs every libFuzzer target
   for --seconds as fuzz/run_fuzzer.cmake does (a fresh corpus directory, the
   seeds, fuzz/regressions/<kind>, -rss_limit_mb=2048 -timeout=10), reading
   libFuzzer's executed units and the crash inputs it wrote; a target that
   fuzz/CMakeLists.txt keeps REPLAY_ONLY (an open finding) runs with -fork=1
   and every kind of crash ignored, so that its crash inputs are counted
   rather than ending the run at the first;
4. writes both tables into docs/reliability.md between the reliability-table
   markers.

Exits 1 when a hostile-input test fails or a target that should be clean
crashes (the tables are written all the same), 2 when something could not
run at all. Standard library only.
"""

import argparse
import datetime
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BUILD = ROOT / "build"
BUILD_FUZZ = ROOT / "build-fuzz"
DOC = ROOT / "docs" / "reliability.md"
BEGIN = "<!-- reliability-table:begin -->"
END = "<!-- reliability-table:end -->"

# The fuzz targets in the order of docs/fuzzing.md's table, with what each reads.
TARGETS = [
    ("nifti", "`.nii`, `.nii.gz`"),
    ("nrrd", "`.nrrd` (attached data)"),
    ("metaimage", "`.mha` (local data)"),
    ("stl", "`.stl`"),
    ("ply", "`.ply`"),
    ("obj", "`.obj`"),
    ("vtp", "`.vtp`"),
    ("msh", "`.msh`"),
    ("vdb", "`.vdb`"),
    ("case", "`scalemesh.toml`"),
]

# run_fuzzer.cmake's limits.
FUZZ_LIMITS = ["-rss_limit_mb=2048", "-timeout=10", "-print_final_stats=1"]
# For a target with an open finding: keep fuzzing past each crash input.
KEEP_GOING = ["-fork=1", "-ignore_crashes=1", "-ignore_ooms=1", "-ignore_timeouts=1"]
# Files libFuzzer writes to the artifact prefix for a crash input.
ARTIFACT = re.compile(r"^(crash|oom|timeout|leak|slow-unit)-")


class Failure(Exception):
    """Something the script could not run at all."""


def say(text):
    print(text, flush=True)


def run(command, **kwargs):
    say("$ " + " ".join(shlex.quote(str(c)) for c in command))
    return subprocess.run([str(c) for c in command], cwd=ROOT, **kwargs)


def build():
    for build_dir, target in ((BUILD, "test_reliability"), (BUILD_FUZZ, "fuzzers")):
        if run(["cmake", "--build", build_dir, "-j2", "--target", target]).returncode != 0:
            raise Failure(f"building {target} in {build_dir} failed")


# ---------------------------------------------------------------- hostile input


def hostile_tests():
    """[{name, input, outcome, result, seconds}] from one run of HostileInput.*."""
    binary = BUILD / "tests" / "reliability" / "test_reliability"
    scalemesh = BUILD / "src" / "cli" / "scalemesh"
    for path in (binary, scalemesh):
        if not path.exists():
            raise Failure(f"{path} is not built (run without --no-build)")
    with tempfile.TemporaryDirectory(prefix="reliability-table-") as tmp:
        report = Path(tmp) / "hostile.json"
        # ctest's environment and working directory (tests/CMakeLists.txt).
        env = dict(os.environ, SCALEMESH_BINARY=str(scalemesh))
        done = run([binary, "--gtest_filter=HostileInput.*", f"--gtest_output=json:{report}"], env=env, timeout=3600)
        if not report.exists():
            raise Failure(f"{binary.name} wrote no JSON report (exit code {done.returncode})")
        data = json.loads(report.read_text())
    tests = []
    for suite in data["testsuites"]:
        for case in suite["testsuite"]:
            failures = case.get("failures", [])
            if failures:
                # GoogleTest's failure text begins with "<file>:<line>".
                where = failures[0]["failure"].strip().splitlines()[0]
                result = f"failed: {len(failures)} assertion(s), the first at {Path(where).name}"
            elif case.get("result") == "SKIPPED":
                result = "skipped"
            else:
                result = "passed"
            tests.append({
                "name": case["name"],
                "input": case.get("input", "(not recorded)"),
                "outcome": case.get("outcome", "(not recorded)"),
                "result": result,
                "seconds": float(case.get("time", "0s").rstrip("s")),
            })
    if not tests:
        raise Failure("no HostileInput test ran")
    return tests


# ---------------------------------------------------------------------- fuzzing


def replay_only_kinds():
    """The kinds fuzz/CMakeLists.txt declares REPLAY_ONLY: their ctest test only replays."""
    text = (ROOT / "fuzz" / "CMakeLists.txt").read_text()
    return set(re.findall(r"scalemesh_fuzzer\(\s*(\w+)\s+REPLAY_ONLY", text))


def file_names(directory):
    return sorted(p.name for p in directory.iterdir() if p.is_file()) if directory.is_dir() else []


def fuzz_target(kind, seconds, keep_going):
    """One bounded run of fuzz_<kind>: executions, crash inputs, exit code."""
    fuzzer = BUILD_FUZZ / "fuzz" / f"fuzz_{kind}"
    seeds = BUILD_FUZZ / "fuzz" / "seeds" / kind
    regressions = ROOT / "fuzz" / "regressions" / kind
    if not fuzzer.exists():
        raise Failure(f"{fuzzer} is not built (run without --no-build)")
    if not seeds.is_dir():
        raise Failure(f"{seeds} is missing: the fuzz_seeds test did not make it")
    work = BUILD_FUZZ / "fuzz" / "table-runs" / kind
    shutil.rmtree(work, ignore_errors=True)
    (work / "corpus").mkdir(parents=True)
    (work / "artifacts").mkdir()
    corpora = [work / "corpus", seeds] + ([regressions] if regressions.is_dir() else [])
    command = [fuzzer, *corpora, f"-max_total_time={seconds}", *FUZZ_LIMITS,
               f"-artifact_prefix={work / 'artifacts'}/"] + (KEEP_GOING if keep_going else [])
    log = work / "fuzz.log"
    start = time.monotonic()
    with open(log, "w") as out:
        # libFuzzer stops itself; the margin covers a last input's -timeout and the exit.
        done = run(command, stdout=out, stderr=subprocess.STDOUT, timeout=seconds + 300)
    elapsed = time.monotonic() - start
    text = log.read_text(errors="replace")
    if keep_going:
        # Fork mode: the parent's progress lines count every job's executions.
        progress = re.findall(r"^#(\d+): cov: .*oom/timeout/crash: (\d+)/(\d+)/(\d+)", text, re.M)
        executions = int(progress[-1][0]) if progress else None
    else:
        found = re.findall(r"^stat::number_of_executed_units: (\d+)", text, re.M)
        executions = int(found[-1]) if found else None
    artifacts = [name for name in file_names(work / "artifacts") if ARTIFACT.match(name)]
    return {
        "kind": kind,
        "seconds": elapsed,
        "executions": executions,
        "artifacts": artifacts,
        "exit_code": done.returncode,
        "work": work,
        "log": log,
        "keep_going": keep_going,
        "regressions": file_names(regressions),
        "known": file_names(ROOT / "fuzz" / "known" / kind),
    }


def fuzz_all(seconds):
    if run(["ctest", "--test-dir", BUILD_FUZZ, "-R", "fuzz_seeds"]).returncode != 0:
        raise Failure("ctest -R fuzz_seeds failed: no seed corpus")
    keep_going = replay_only_kinds()
    runs = []
    for kind, _ in TARGETS:
        r = fuzz_target(kind, seconds, kind in keep_going)
        r["crashed"] = not r["keep_going"] and (r["exit_code"] != 0 or bool(r["artifacts"]))
        say(f"fuzz_{kind}: {r['executions']} executions in {r['seconds']:.0f} s, "
            f"{len(r['artifacts'])} crash inputs, exit code {r['exit_code']}, log {r['log'].relative_to(ROOT)}")
        runs.append(r)
    return runs


# ------------------------------------------------------------------------ table


def cell(text):
    return str(text).replace("|", "\\|").replace("\n", " ")


def code_list(names):
    return ", ".join(f"`{n}`" for n in names)


def fuzz_status(r):
    kind = r["kind"]
    parts = []
    if r["crashed"]:
        found = code_list(r["artifacts"]) or "no file"
        parts.append(f"**crashed** (exit code {r['exit_code']}): {found} in "
                     f"`{r['work'].relative_to(ROOT)}/artifacts`")
    if r["known"]:
        parts.append(f"open: {code_list(r['known'])} in `fuzz/known/{kind}`")
    if r["regressions"]:
        parts.append(f"fixed: {code_list(r['regressions'])} in `fuzz/regressions/{kind}`")
    if not parts:
        parts.append(f"clean; nothing in `fuzz/regressions/{kind}`")
    return "; ".join(parts)


def crash_count(r):
    if not r["artifacts"]:
        return "0"
    kinds = {}
    for name in r["artifacts"]:
        prefix = name.split("-")[0] if not name.startswith("slow-unit") else "slow-unit"
        kinds[prefix] = kinds.get(prefix, 0) + 1
    return f"{len(r['artifacts'])} (" + ", ".join(f"{n} {k}" for k, n in sorted(kinds.items())) + ")"


def commit():
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT, capture_output=True,
                           text=True)
    if head.returncode != 0:
        return "an unknown commit"
    return f"commit {head.stdout.strip()}" + (" with uncommitted changes" if dirty.stdout.strip() else "")


def tables(fuzz, hostile, seconds, started, load, command):
    formats = dict(TARGETS)
    lines = [
        f"Generated {started:%Y-%m-%d %H:%M} UTC on {os.cpu_count()} cores (load average {load:.1f} at the start), "
        f"{seconds} s per fuzz target, at {commit()}, by `{command}`.",
        "",
        "| target | reads | seconds (wall) | executions | crash inputs found | status |",
        "|---|---|---|---|---|---|",
    ]
    for r in fuzz:
        mode = " (`-fork=1`, crashes ignored)" if r["keep_going"] else ""
        executions = "not reported" if r["executions"] is None else f"{r['executions']:,}"
        lines.append(f"| `fuzz_{r['kind']}`{mode} | {formats[r['kind']]} | {r['seconds']:.0f} | {executions} | "
                     f"{crash_count(r)} | {cell(fuzz_status(r))} |")
    lines += ["", "| test | input | outcome | result |", "|---|---|---|---|"]
    for t in hostile:
        lines.append(f"| `{t['name']}` | {cell(t['input'])} | {cell(t['outcome'])} | "
                     f"{cell(t['result'])}, {t['seconds']:.1f} s |")
    return "\n".join(lines)


def write_doc(doc, text):
    content = doc.read_text()
    begin, end = content.find(BEGIN), content.find(END)
    if begin < 0 or end < begin:
        raise Failure(f"{doc} has no {BEGIN} ... {END} markers")
    doc.write_text(content[:begin + len(BEGIN)] + "\n" + text + "\n" + content[end:])


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=int, default=60, help="fuzzing time per target (default 60)")
    parser.add_argument("--no-build", action="store_true", help="use the builds as they are")
    parser.add_argument("--doc", type=Path, default=DOC, help="the file to write into (default docs/reliability.md)")
    args = parser.parse_args()
    command = "python3 " + " ".join(shlex.quote(a) for a in
                                    [os.path.relpath(Path(sys.argv[0]).resolve(), ROOT)] + sys.argv[1:])
    started = datetime.datetime.now(datetime.timezone.utc)
    load = os.getloadavg()[0]
    try:
        if not args.no_build:
            build()
        hostile = hostile_tests()
        for t in hostile:
            say(f"{t['name']}: {t['result']}: {t['outcome']}")
        fuzz = fuzz_all(args.seconds)
        write_doc(args.doc, tables(fuzz, hostile, args.seconds, started, load, command))
    except (Failure, subprocess.TimeoutExpired) as e:
        say(f"reliability_table.py: {e}")
        return 2
    say(f"wrote the tables into {args.doc}")
    failed = [t["name"] for t in hostile if t["result"].startswith("failed")]
    crashed = [f"fuzz_{r['kind']}" for r in fuzz if r["crashed"]]
    for name in failed:
        say(f"FAILED: HostileInput.{name}")
    for name in crashed:
        say(f"CRASHED: {name} (log and input under build-fuzz/fuzz/table-runs/)")
    return 1 if failed or crashed else 0


if __name__ == "__main__":
    sys.exit(main())
