#!/usr/bin/python3
"""Checks the recipes of docs/core.md, "Where to add what", against the tree,
so that they fail when the code moves and the docs do not (issue 26).

Each recipe is a "### " subsection of that section holding a numbered list;
every item names the files it touches as backticked repository paths
(`server/storage/store.h`, `core/tasks/scene.{h,cc}`; a path with a
<placeholder> is a file the change creates). The checks:

  (a) every recipe is there, every numbered item names at least one file,
      every path its subsection names exists (for a new file, the folder
      before its first placeholder), and no code span is broken across
      lines (the paths after it would go unread);
  (b) completeness: a recipe's markers name the existing instance a new one
      is added beside (the study job kind, the DEL and GTP+sn methods, the
      double pendulum's plant and scenes, issue 27's episode columns). Every
      product file (core/, server/, worker/, client/, results/, proto/, io/)
      that matches one must be in the recipe's numbered items or in its
      ALLOWED list: files that name the instance but need no change for a new
      one, each with the reason. An ALLOWED entry that no longer matches, or
      that the recipe also lists, is an error too, and so is a marker that
      matches no product file (what it names was renamed: the rule would
      check less than it says).

Usage: recipes_test.py [SOURCE_DIR]   (default: the repository holding this
script). Exit 1 naming each problem. Standard library only.
"""
import os
import re
import sys

DOC = "docs/core.md"
SECTION = "## Where to add what"
PRODUCT_DIRS = ("core", "runtime", "server", "worker", "client", "results", "proto", "io")


class Recipe:
    def __init__(self, heading, markers, allowed):
        self.heading = heading  # the "### " title
        # Patterns, any of which marks a file. Each starts with a literal, so
        # that re finds it fast (a leading \b would make it try every
        # position: seconds instead of milliseconds over the tree).
        self.markers = [re.compile(marker) for marker in markers]
        self.allowed = allowed  # path -> why it needs no change

    def find(self, text):
        """The first marker text found in `text`, or None."""
        for marker in self.markers:
            match = marker.search(text)
            if match:
                return match.group(0)
        return None


RECIPES = [
    Recipe(
        "A new estimator",
        # DEL is the newest method and, as a new one would be, not one of
        # the paper's Table 1; GTP+sn's enumerator and name add the places
        # that list the paper's methods. Hand-written lists of every method
        # ("GTP+sn, DEL") count too.
        [r'kDel\b', r'kGtpSn\b', r'"DEL"', r'"GTP\+sn"', r'GTP\+sn,? (?:or )?DEL\b'],
        {
            "results/table1.cc":
                "the paper's Table 1 grid: its eight methods only; a new "
                "method's trials are listed outside it",
            "results/table1_claims.cc":
                "the paper's claims compare the paper's methods only",
        }),
    Recipe(
        "A new plant or scene",
        # The double pendulum is a plant other than the paper's cart-pole
        # (code that tests for the cart-pole alone is generic for the rest);
        # its two scenes' names stand for any catalog name written in code.
        [r'enum class PlantKind', r'kDoublePendulum\b', r'"pendubot"', r'"double-pendulum"'],
        {
            "server/sweep/sweep_spec.h":
                "a sweep-file example in a comment; a [[study]] scene is any "
                "catalog name, checked by the catalog",
        }),
    Recipe(
        "A new results column",
        # Columns every full list of the episode record's fields names
        # (issue 27's, the newest, shown in no view): where such lists are
        # written by hand, a new column goes too.
        [r'ess_low_fraction\b', r'gradient_snr_mean\b'],
        {
            "client/service_commands/diagnostics_command.cc":
                "names one statistic as an example in its help text; the "
                "statistics are the record's fields (results/diagnostics.cc)",
            "server/dashboard/assets/dashboard.js":
                "the sweep page's first statistic shown; the picker lists "
                "every statistic /api/diagnostics names",
        }),
    Recipe(
        "A new job kind",
        # The study kind: its enumerators and its name on the wire, the
        # workers' capability flag, its tables, rows and their counts, the
        # rows' member of the result bundles (`results.study`), their
        # readers, its sweep-file entry, its lease payload and its runner.
        [r'JobKind::kStudy\b', r'JOB_KIND_STUDY\b', r'enum class JobKind\b', r'study_jobs\b',
         r'study_cells\b', r'study_references\b', r'StudyCellRow\b', r'StudyRows\b',
         r'study_rows\b', r'\.study\b(?!\(|::)', r'PrintStudyResults\b', r'StudyEntry\b',
         r'spec(?:->|\.)studies\b', r'study_spec_json\b', r'CoreStudyRunner\b',
         r'study_runner\.(?:h|cc)\b', r'totalgrad_worker_study\b'],
        {
            "worker/study_runner.h":
                "the study's own runner; a new kind has a runner of its own",
            "worker/study_runner.cc":
                "the study's own runner; a new kind has a runner of its own",
            "client/service_commands/study_results.cc":
                "the study's own results command; a new kind has its own",
            "runtime/record_proto.h":
                "converts any record by its field table; its comment names "
                "the study runner as one user",
            "server/service/worker_service.cc":
                "one Heartbeat and one Complete path for every kind; the "
                "heartbeat answer's count of stored study rows is for "
                "information only (no worker reads it)",
        }),
]

BACKTICKED = re.compile(r"`([^`\n]+)`")
# A repository path as the recipes write one: no spaces, quotes or calls.
PATH_TOKEN = re.compile(r"[\w.<>{},/+-]+")
FILE_NAME = re.compile(r"[\w.-]+\.(?:md|txt|cc|h|py|sh|proto|toml|json|js)")
NUMBERED_ITEM = re.compile(r"^(\d+)\.\s")


def expand_braces(path):
    """core/x.{h,cc} -> [core/x.h, core/x.cc] (any number of groups)."""
    match = re.search(r"\{([^{}]*)\}", path)
    if not match:
        return [path]
    expanded = []
    for choice in match.group(1).split(","):
        expanded += expand_braces(path[:match.start()] + choice + path[match.end():])
    return expanded


def paths_in(text):
    """The repository paths backticked in `text`, braces expanded."""
    paths = []
    for token in BACKTICKED.findall(text):
        if not PATH_TOKEN.fullmatch(token):
            continue
        if "/" in token or FILE_NAME.fullmatch(token):
            paths += expand_braces(token)
    return paths


def split_recipes(doc_text):
    """{"### " title: its text} of the "Where to add what" section, or None
    when the section is missing."""
    lines = doc_text.splitlines()
    try:
        start = next(i for i, line in enumerate(lines) if line.strip() == SECTION)
    except StopIteration:
        return None
    recipes, title = {}, None
    for line in lines[start + 1:]:
        if line.startswith("## "):
            break
        if line.startswith("### "):
            title = line[4:].strip()
            recipes[title] = []
        elif title is not None:
            recipes[title].append(line)
    return {title: "\n".join(body) for title, body in recipes.items()}


def numbered_items(recipe_text):
    """The numbered list's items (an item runs until the next item, a blank
    line or a line that is not indented)."""
    items, current = [], None
    for line in recipe_text.splitlines():
        if NUMBERED_ITEM.match(line):
            current = [line]
            items.append(current)
        elif current is not None and line.startswith(" ") and line.strip():
            current.append(line)
        else:
            current = None
    return ["\n".join(item) for item in items]


def exists(root, path):
    """A path exists; a new file's (with a <placeholder>) folder does."""
    if "<" in path:
        folder = path[:path.index("<")].rsplit("/", 1)[0]
        return os.path.isdir(os.path.join(root, folder))
    return os.path.exists(os.path.join(root, path))


def product_files(root):
    """{repository path: text} of every product file."""
    files = {}
    for top in PRODUCT_DIRS:
        for folder, dirs, names in os.walk(os.path.join(root, top)):
            dirs[:] = sorted(d for d in dirs if not d.startswith((".", "build")))
            for name in sorted(names):
                full = os.path.join(folder, name)
                with open(full, encoding="utf-8", errors="replace") as f:
                    files[os.path.relpath(full, root).replace(os.sep, "/")] = f.read()
    return files


def check(doc_text, root, recipes=RECIPES, files=None):
    """Problems found, as sentences; none when the recipes are true."""
    if files is None:
        files = product_files(root)
    sections = split_recipes(doc_text)
    if sections is None:
        return [f"{DOC}: no section '{SECTION}'"]
    problems = []
    for recipe in recipes:
        title = next((t for t in sections if t.startswith(recipe.heading)), None)
        if title is None:
            problems.append(f"{DOC}: no recipe '### {recipe.heading}' under '{SECTION}'")
            continue
        where = f"{DOC}, '{title}'"
        text = sections[title]
        # A code span broken across lines pairs the wrong backticks, and the
        # paths after it would be read as prose and go unchecked.
        for line in text.splitlines():
            if line.count("`") % 2:
                problems.append(f"{where}: a code span is broken across lines at "
                                f"'{line.strip()[:60]}': keep each on one line")
        items = numbered_items(text)
        if not items:
            problems.append(f"{where}: no numbered list of files")
        listed = set()
        for item in items:
            named = paths_in(item)
            if not named:
                first = item.splitlines()[0]
                problems.append(f"{where}: item '{first[:60]}' names no file")
            listed.update(named)
        for path in sorted(set(paths_in(text))):
            if not exists(root, path):
                problems.append(f"{where}: {path} does not exist")
        found = {path: recipe.find(content) for path, content in files.items()}
        matching = {path for path, marked in found.items() if marked is not None}
        for marker in recipe.markers:
            if not any(marker.search(files[path]) for path in matching):
                problems.append(f"{where}: marker '{marker.pattern}' matches no product file: "
                                f"what it names was renamed or removed; update the markers "
                                f"in {os.path.basename(__file__)}")
        for path in sorted(matching - listed - set(recipe.allowed)):
            problems.append(f"{where}: {path} names '{found[path]}' but is not in the recipe's "
                            f"list (nor in the test's allow-list)")
        for path in sorted(recipe.allowed):
            if path not in files:
                problems.append(f"{where}: allow-listed {path} does not exist")
            elif path not in matching:
                problems.append(f"{where}: allow-listed {path} no longer matches a marker: "
                                f"remove it from the allow-list")
            if path in listed:
                problems.append(f"{where}: {path} is both in the recipe and allow-listed "
                                f"as needing no change")
    return problems


def main(argv):
    root = argv[1] if len(argv) > 1 else os.path.dirname(
        os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    with open(os.path.join(root, DOC), encoding="utf-8") as f:
        doc_text = f.read()
    problems = check(doc_text, root)
    for problem in problems:
        print(problem)
    if problems:
        print(f"{len(problems)} problem(s): the recipes of {DOC} are not the code's")
        return 1
    print(f"{len(RECIPES)} recipes of {DOC} match the tree")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
