#!/usr/bin/python3
"""clang's -Wthread-safety over the project's translation units (g++ ignores
ABSL_GUARDED_BY and friends; clang checks them).

Reads build/compile_commands.json, keeps the project's own sources (by
default those whose project includes never reach <torch/...>: LibTorch
headers cost clang ~15 s and ~1 GB per unit), and runs each with clang++
-fsyntax-only, the build's flags, and -Werror=thread-safety: an access to a
guarded field without its mutex, a lock not released, a call to a function
that requires a lock without it, fail the check. Other clang warnings are
off: this check is about locks only. Exit 0 when every unit passes.
    tests/thread_safety.py BUILD_DIR [-j N] [--with-torch]
--with-torch checks the LibTorch units too (the ctest does: ~100 s in all).
"""
import argparse
import concurrent.futures
import json
import os
import re
import shlex
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
INCLUDE = re.compile(r'^\s*#\s*include\s*([<"])([^>"]+)[>"]', re.M)
FLAGS = ["-fsyntax-only", "-Wno-everything", "-Wthread-safety", "-Werror=thread-safety"]


def reaches_torch(path, seen):
    """True if `path` or a project header it includes (transitively) includes torch."""
    if path in seen:
        return False
    seen.add(path)
    try:
        with open(path, errors="replace") as f:
            text = f.read()
    except OSError:
        return False
    for kind, name in INCLUDE.findall(text):
        if name.startswith("torch/") or name.startswith("ATen/"):
            return True
        if kind == '"':
            header = os.path.join(ROOT, name)
            if os.path.exists(header) and reaches_torch(header, seen):
                return True
    return False


def clang_command(entry):
    args = entry["arguments"] if "arguments" in entry else shlex.split(entry["command"])
    out = ["clang++"]
    skip = False
    for i, arg in enumerate(args[1:], 1):
        if skip:
            skip = False
            continue
        if arg in ("-o", "-c", "-MF", "-MT", "-MQ"):
            skip = arg != "-c"
            continue
        if arg in ("-MD", "-MMD", "-Winvalid-pch"):
            continue
        # GCC's precompiled header (CMake's cmake_pch.hxx, a .gch beside it)
        # is not clang's; every unit includes what it uses anyway.
        if arg == "-include" and i + 1 < len(args) and "cmake_pch" in args[i + 1]:
            skip = True
            continue
        out.append(arg)
    return out + FLAGS


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("build")
    parser.add_argument("-j", type=int, default=2)
    parser.add_argument("--with-torch", action="store_true", help="check the units that include LibTorch too")
    args = parser.parse_args()
    with open(os.path.join(args.build, "compile_commands.json")) as f:
        entries = json.load(f)
    build = os.path.realpath(args.build)
    units, skipped = [], []
    for entry in entries:
        path = os.path.realpath(os.path.join(entry["directory"], entry["file"]))
        if not path.startswith(ROOT + os.sep) or path.startswith(build + os.sep):
            continue  # Generated protobuf code and anything outside the project.
        (skipped if reaches_torch(path, set()) and not args.with_torch else units).append((path, entry))
    if not units:
        print("thread_safety: no translation units found", file=sys.stderr)
        return 1
    start = time.time()

    def check(unit):
        path, entry = unit
        r = subprocess.run(clang_command(entry), cwd=entry["directory"], capture_output=True, text=True)
        return path, r.returncode, r.stderr

    failed = 0
    with concurrent.futures.ThreadPoolExecutor(max_workers=args.j) as pool:
        for path, code, err in pool.map(check, units):
            if code != 0:
                failed += 1
                print(f"FAIL {os.path.relpath(path, ROOT)}\n{err}", file=sys.stderr)
    print(f"thread_safety: {len(units) - failed}/{len(units)} translation units pass -Wthread-safety "
          f"({len(skipped)} with LibTorch not checked: {', '.join(sorted(os.path.relpath(p, ROOT) for p, _ in skipped))}) "
          f"in {time.time() - start:.0f} s")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
