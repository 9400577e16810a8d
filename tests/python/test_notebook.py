"""docs/python-tour.ipynb runs from top to bottom in a fresh kernel (Debian's
python3-nbclient and python3-ipykernel), and every cell tagged
"check-output" prints what the committed notebook shows: Table 1 and the
curves from a committed archive, and a trial in-process (the same bits on
every run of a build).

Regenerate the committed outputs after a change that moves them with
    PYTHONPATH=build/python TOTALGRAD_NOTEBOOK_WRITE=1 /usr/bin/python3 -m pytest tests/python/test_notebook.py
"""
import copy
import os

import nbclient
import nbformat

REPO = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
NOTEBOOK = os.path.join(REPO, "docs", "python-tour.ipynb")


def text_of(cell):
    """What a cell printed and displayed, as text (pictures left out)."""
    parts = []
    for output in cell.get("outputs", []):
        if output.get("output_type") == "stream":
            parts.append(output.get("text", ""))
        elif "data" in output and "text/plain" in output["data"]:
            parts.append(output["data"]["text/plain"])
    return "".join(parts)


def test_the_tour_runs_and_prints_what_is_committed():
    committed = nbformat.read(NOTEBOOK, as_version=4)
    notebook = copy.deepcopy(committed)
    os.environ["TOTALGRAD_REPO"] = REPO
    client = nbclient.NotebookClient(notebook, timeout=600, kernel_name="python3",
                                     resources={"metadata": {"path": os.path.join(REPO, "docs")}})
    client.execute()  # raises CellExecutionError naming the cell on any error
    checked = 0
    for ours, theirs in zip(notebook.cells, committed.cells):
        if "check-output" not in ours.metadata.get("tags", []):
            continue
        checked += 1
        if not os.environ.get("TOTALGRAD_NOTEBOOK_WRITE"):
            assert text_of(ours) == text_of(theirs), ours.source[:80]
    assert checked >= 4
    if os.environ.get("TOTALGRAD_NOTEBOOK_WRITE"):
        nbformat.write(notebook, NOTEBOOK)
