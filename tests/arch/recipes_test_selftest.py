#!/usr/bin/python3
"""Shows that recipes_test.py fails when the recipes go stale: the checker
runs on doctored copies of docs/core.md against this tree (a path that does
not exist, a file dropped from a recipe, a recipe or an item without files,
a code span broken across lines)
and on a small made-up tree (a new product file naming a recipe's instance,
allow-list entries that are stale or contradict the recipe, a marker that
matches nothing). Each case must be reported, naming the file.

Usage: recipes_test_selftest.py [SOURCE_DIR]. Standard library only.
"""
import os
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import recipes_test  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def real_doc():
    with open(os.path.join(ROOT, recipes_test.DOC), encoding="utf-8") as f:
        return f.read()


def doctored(old, new):
    """The real doc with `old` (which must be there) replaced by `new`."""
    text = real_doc()
    if old not in text:
        raise AssertionError(f"the doc no longer holds {old!r}: update this self-test")
    return text.replace(old, new)


class RealDocTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.files = recipes_test.product_files(ROOT)

    def problems(self, doc_text):
        return recipes_test.check(doc_text, ROOT, files=self.files)

    def assertReported(self, problems, *fragments):
        for problem in problems:
            if all(fragment in problem for fragment in fragments):
                return
        self.fail(f"no problem names {fragments}; reported: {problems}")

    def test_the_tree_as_it_is_passes(self):
        self.assertEqual(self.problems(real_doc()), [])

    def test_a_path_that_does_not_exist_is_reported(self):
        problems = self.problems(doctored("`core/estimators/method.cc`",
                                          "`core/estimators/methods.cc`"))
        self.assertReported(problems, "A new estimator", "core/estimators/methods.cc",
                            "does not exist")
        # and the real file, now missing from the list, too
        self.assertReported(problems, "core/estimators/method.cc", "not in the recipe")

    def test_a_file_dropped_from_a_recipe_is_reported(self):
        problems = self.problems(doctored("`server/storage/sqlite_import.cc`",
                                          "the import"))
        self.assertReported(problems, "A new job kind", "server/storage/sqlite_import.cc",
                            "not in the recipe")

    def test_a_hand_written_method_list_left_out_is_reported(self):
        problems = self.problems(doctored(
            "7. `client/core_commands/bench_gradients_command.cc`: the `--method` help,",
            "7. the `--method` help of bench gradients,"))
        self.assertReported(problems, "A new estimator",
                            "client/core_commands/bench_gradients_command.cc",
                            "not in the recipe")

    def test_a_code_span_broken_across_lines_is_reported(self):
        problems = self.problems(doctored("`ALTER TABLE episodes ADD COLUMN foo REAL`",
                                          "`ALTER TABLE episodes ADD\n   COLUMN foo REAL`"))
        self.assertReported(problems, "A new results column", "broken across lines")

    def test_a_missing_recipe_is_reported(self):
        problems = self.problems(doctored("### A new plant or scene", "### Plants"))
        self.assertReported(problems, "no recipe", "A new plant or scene")

    def test_a_missing_section_is_reported(self):
        problems = self.problems(doctored(recipes_test.SECTION, "## Recipes"))
        self.assertReported(problems, "no section")

    def test_an_item_without_a_file_is_reported(self):
        problems = self.problems(doctored(
            "### A new results column\n",
            "### A new results column\n1. somewhere in the store.\n\n"))
        self.assertReported(problems, "A new results column", "names no file")


class MadeUpTreeTest(unittest.TestCase):
    """A tree of three product files and a doc with one recipe, whose marker
    is the word `sample_kind`."""

    DOC_TEXT = """# Core

## Where to add what
### A new thing
1. `core/listed.cc`: its line.
2. `docs/core.md`: this.

Prose may name `core/elsewhere.cc`, which is checked to exist only.

## Next
"""

    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.root = self.tmp.name
        for path, text in {"docs/core.md": self.DOC_TEXT,
                           "core/listed.cc": "int sample_kind = 1;\n",
                           "core/elsewhere.cc": "// nothing here\n",
                           "core/follows.cc": "// reads sample_kind from the table\n"}.items():
            self.write(path, text)
        self.recipe = recipes_test.Recipe(
            "A new thing", [r"sample_kind\b"], {"core/follows.cc": "reads the table"})

    def tearDown(self):
        self.tmp.cleanup()

    def write(self, path, text):
        full = os.path.join(self.root, path)
        os.makedirs(os.path.dirname(full), exist_ok=True)
        with open(full, "w", encoding="utf-8") as f:
            f.write(text)

    def problems(self, recipe=None):
        return recipes_test.check(self.DOC_TEXT, self.root, recipes=[recipe or self.recipe])

    def test_the_made_up_tree_passes(self):
        self.assertEqual(self.problems(), [])

    def test_a_new_product_file_naming_the_instance_is_reported(self):
        self.write("server/new_switch.cc", "case sample_kind: break;\n")
        problems = self.problems()
        self.assertEqual(len(problems), 1, problems)
        self.assertIn("server/new_switch.cc names 'sample_kind'", problems[0])

    def test_tests_docs_and_build_folders_are_not_product_files(self):
        self.write("tests/core/listed_test.cc", "sample_kind\n")
        self.write("docs/notes.md", "sample_kind\n")
        self.write("core/build/generated.cc", "sample_kind\n")
        self.assertEqual(self.problems(), [])

    def test_a_stale_allow_list_entry_is_reported(self):
        self.write("core/follows.cc", "// reads the table\n")
        problems = self.problems()
        self.assertEqual(len(problems), 1, problems)
        self.assertIn("allow-listed core/follows.cc no longer matches a marker", problems[0])

    def test_an_allow_listed_file_the_recipe_lists_is_reported(self):
        recipe = recipes_test.Recipe("A new thing", [r"sample_kind\b"],
                                     {"core/follows.cc": "reads the table",
                                      "core/listed.cc": "contradicts the recipe"})
        problems = self.problems(recipe)
        self.assertTrue(any("core/listed.cc is both in the recipe and allow-listed" in p
                            for p in problems), problems)

    def test_a_marker_that_matches_nothing_is_reported(self):
        recipe = recipes_test.Recipe("A new thing", [r"sample_kind\b", r"renamed_kind\b"],
                                     {"core/follows.cc": "reads the table"})
        problems = self.problems(recipe)
        self.assertEqual(len(problems), 1, problems)
        self.assertIn("marker 'renamed_kind\\b' matches no product file", problems[0])

    def test_a_missing_prose_path_is_reported(self):
        os.remove(os.path.join(self.root, "core/elsewhere.cc"))
        problems = self.problems()
        self.assertEqual(problems, ["docs/core.md, 'A new thing': core/elsewhere.cc does not exist"])


class PathsTest(unittest.TestCase):
    def test_paths_braces_and_placeholders(self):
        self.assertEqual(
            recipes_test.paths_in("`server/a.{h,cc}` `worker/<kind>_runner.{h,cc}` `README.md` "
                                  "`JobKind::kStudy` `-f csv|json` `\"episodes/<sweep>\"` "
                                  "`kSchemaVersion`"),
            ["server/a.h", "server/a.cc", "worker/<kind>_runner.h", "worker/<kind>_runner.cc",
             "README.md"])

    def test_a_new_file_needs_its_folder(self):
        self.assertTrue(recipes_test.exists(ROOT, "worker/<kind>_runner.h"))
        self.assertTrue(recipes_test.exists(ROOT, "core/<module>/<name>_records.h"))
        self.assertFalse(recipes_test.exists(ROOT, "nowhere/<kind>_runner.h"))


if __name__ == "__main__":
    if len(sys.argv) > 1 and not sys.argv[1].startswith("-"):
        ROOT = os.path.abspath(sys.argv.pop(1))
    unittest.main()
