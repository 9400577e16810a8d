#!/usr/bin/python3
"""format_versions_test.py must fail on a stale docs/formats.md: a bumped
constant, a missing changelog line, a missing row."""
import os
import shutil
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import format_versions_test  # noqa: E402


def copy_tree(root, dest):
    for path in ["docs/formats.md", "server/storage/sqlite_schema.h",
                 "server/service/sweep_archive.h", "core/learner/checkpoint.h",
                 "worker/spool.h"]:
        os.makedirs(os.path.dirname(os.path.join(dest, path)), exist_ok=True)
        shutil.copy(os.path.join(root, path), os.path.join(dest, path))


def edit(path, old, new):
    text = open(path).read()
    assert old in text, (path, old)
    open(path, "w").write(text.replace(old, new, 1))


def main():
    root = sys.argv[1]
    failures = []
    assert format_versions_test.problems_in(root) == [], "the real tree must pass first"
    cases = [
        ("a bumped constant", "server/service/sweep_archive.h",
         "kSweepArchiveVersion = 4;", "kSweepArchiveVersion = 5;"),
        ("a missing changelog line", "docs/formats.md",
         "- 2: each episode also lists", "- two: each episode also lists"),
        ("a missing row", "docs/formats.md", "| worker spool file |", "| spool |"),
    ]
    for name, path, old, new in cases:
        with tempfile.TemporaryDirectory() as dest:
            copy_tree(root, dest)
            edit(os.path.join(dest, path), old, new)
            if not format_versions_test.problems_in(dest):
                failures.append(name)
    for name in failures:
        print(f"not detected: {name}")
    print(f"{len(cases) - len(failures)} of {len(cases)} doctored copies detected")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
