#!/usr/bin/python3
"""docs/formats.md against the version constants of the code.

    format_versions_test.py REPO_ROOT

For each versioned format the page's table names a constant (in backticks,
with its header in the next backticks) and a current version: the constant
must be defined in that header with that value, and the format's section
must have a changelog line "- N:" for every version 1..N. Exits 1 naming
each disagreement, so the page cannot fall behind a version bump.
"""
import os
import re
import sys

# The table's format name -> the heading of its changelog section.
SECTIONS = {
    "coordinator database": "Coordinator database (schema)",
    "sweep archive": "Sweep archive",
    "trial checkpoint": "Trial checkpoint",
    "worker spool file": "Worker spool file",
    "episode trajectories": "Episode trajectories",
}


def problems_in(root):
    text = open(os.path.join(root, "docs/formats.md")).read()
    problems = []
    rows = re.findall(r"^\| ([a-z ]+) \| `(k\w+)` \(`([\w/.]+)`\) \| (\d+) \|", text, re.M)
    named = {row[0] for row in rows}
    for format_name in SECTIONS:
        if format_name not in named:
            problems.append(f"docs/formats.md: no table row for the {format_name}")
    for format_name, constant, header, current in rows:
        path = os.path.join(root, header)
        if not os.path.exists(path):
            problems.append(f"{format_name}: {header} does not exist")
            continue
        defined = re.search(rf"constexpr int {constant} = (\d+);", open(path).read())
        if defined is None:
            problems.append(f"{format_name}: {header} defines no {constant}")
        elif defined.group(1) != current:
            problems.append(f"{format_name}: {constant} is {defined.group(1)} in {header}, "
                            f"docs/formats.md says {current}")
        heading = SECTIONS.get(format_name)
        if heading is None:
            problems.append(f"{format_name}: no changelog section known to this test")
            continue
        section = re.search(rf"^## {re.escape(heading)}\n(.*?)(?=^## |\Z)", text, re.M | re.S)
        if section is None:
            problems.append(f"docs/formats.md: no section '## {heading}'")
            continue
        listed = {int(n) for n in re.findall(r"^- (\d+):", section.group(1), re.M)}
        for version in range(1, int(current) + 1):
            if version not in listed:
                problems.append(f"docs/formats.md, {heading}: no line for version {version}")
    return problems


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else "."
    problems = problems_in(root)
    for problem in problems:
        print(problem)
    if problems:
        print(f"{len(problems)} problem(s): docs/formats.md is not the code's")
        return 1
    print("docs/formats.md: every format's version and changelog match the code")
    return 0


if __name__ == "__main__":
    sys.exit(main())
