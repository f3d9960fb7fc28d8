#!/usr/bin/env python3
"""clang-tidy over a compile database, skipping translation units already clean.

    tidy_cached.py BUILD_DIR FILE_REGEX [--jobs N] [--tidy BINARY] [--cache DIR]

Runs clang-tidy (-p BUILD_DIR --quiet) on every entry of
BUILD_DIR/compile_commands.json whose file matches FILE_REGEX, N at a time,
and prints what it reports. A unit that passes leaves a stamp named by the
hash of everything its result depends on: the clang-tidy version, the
.clang-tidy files on the path from the repository root to the unit, the
unit's path relative to the repository, and its preprocessed text (the
compiler's -E output under the unit's own flags, which holds every header it
includes, project and system). A unit whose stamp exists is not checked
again: the same input gives the same result. Any change to the unit, a header
it includes, the flags or the configuration is a new hash and a new check.
Units that fail leave no stamp. Exit status: 0 when every unit passed, else 1.

The cache (default $VKJR2_TIDY_CACHE, else ~/.cache/vkjr2/tidy) is kept
between runs on the same machine; delete it to check everything again.
"""
import argparse
import concurrent.futures
import hashlib
import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path


def preprocess_command(entry):
    """The entry's compile command with -E -P instead of -c/-o (text only)."""
    args = entry.get("arguments") or shlex.split(entry["command"])
    out = []
    skip = False
    for a in args:
        if skip:
            skip = False
            continue
        if a in ("-o", "-MF", "-MT", "-MQ"):
            skip = True
            continue
        if a in ("-c", "-MD", "-MMD") or a.startswith("-o"):
            continue
        out.append(a)
    return out + ["-E", "-P"]


def unit_key(entry, root, tidy_version):
    directory = entry["directory"]
    path = Path(entry["file"]) if os.path.isabs(entry["file"]) else Path(directory) / entry["file"]
    h = hashlib.sha256()
    h.update(tidy_version.encode())
    rel = os.path.relpath(path, root)
    h.update(rel.encode())
    # .clang-tidy files from the root down to the unit's folder.
    folder = root
    for part in [""] + list(Path(rel).parent.parts):
        folder = folder / part if part else folder
        cfg = folder / ".clang-tidy"
        if cfg.is_file():
            h.update(cfg.read_bytes())
    pre = subprocess.run(preprocess_command(entry), cwd=directory, capture_output=True)
    if pre.returncode != 0:
        return None, path  # let clang-tidy report the problem
    # The clone's own path (in __FILE__ expansions, say) is not part of the key.
    h.update(pre.stdout.replace(str(root).encode(), b"<root>"))
    return h.hexdigest(), path


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("build_dir")
    ap.add_argument("file_regex")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--tidy", default="clang-tidy")
    default_cache = os.environ.get("VKJR2_TIDY_CACHE") or str(Path.home() / ".cache/vkjr2/tidy")
    ap.add_argument("--cache", default=default_cache)
    a = ap.parse_args()

    root = Path(__file__).resolve().parent.parent
    db = Path(a.build_dir) / "compile_commands.json"
    if not db.is_file():
        print(f"tidy: missing {db} (configure the build first)", file=sys.stderr)
        return 1
    pattern = re.compile(a.file_regex)
    entries = []
    for e in json.loads(db.read_text()):
        f = e["file"] if os.path.isabs(e["file"]) else os.path.join(e["directory"], e["file"])
        if pattern.search(f):
            entries.append(e)
    version = subprocess.run([a.tidy, "--version"], capture_output=True, text=True).stdout
    cache = Path(a.cache)
    cache.mkdir(parents=True, exist_ok=True)

    def check(entry):
        key, path = unit_key(entry, root, version)
        stamp = cache / key if key else None
        if stamp is not None and stamp.exists():
            return path, True, True, ""
        r = subprocess.run([a.tidy, "-p", a.build_dir, "--quiet", str(path)],
                           capture_output=True, text=True)
        # "N warnings generated." lines count system headers' warnings, which
        # the header filter hides; they are not findings.
        report = "\n".join(
            line for line in (r.stdout + r.stderr).splitlines()
            if not re.fullmatch(r"\d+ warnings?( and \d+ errors?)? generated\.", line))
        ok = r.returncode == 0 and not re.search(r"(warning|error):", report)
        if ok and stamp is not None:
            stamp.touch()
        return path, ok, False, report

    failed = cached = 0
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, a.jobs)) as pool:
        for path, ok, hit, report in pool.map(check, entries):
            cached += hit
            if not hit:
                print(f"tidy: {os.path.relpath(path, root)}{'' if ok else '  FAILED'}", flush=True)
            if report.strip():
                print(report, flush=True)
            failed += not ok
    print(f"tidy: {len(entries)} units, {cached} unchanged since a clean check, "
          f"{len(entries) - cached} checked, {failed} with findings")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
