#!/usr/bin/python3
"""Checks size_limits.py's function finder on the C++ shapes product code uses:
what it must measure as functions (free and member functions, constructors
with initialiser lists, annotated methods, lambdas) and what it must not
(classes, namespaces, control blocks, brace initialisers, braces inside
comments and string literals)."""
import os
import sys
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import size_limits  # noqa: E402

SOURCE = r'''
namespace a::b {
namespace {
// A comment with a brace { that is not code.
struct Options {
  int x = 0;
  std::vector<int> v{1, 2};
};
}  // namespace

int Free(int x) {
  if (x > 0) {
    for (int i = 0; i < x; ++i) {
      x += i;
    }
  }
  return x;
}

Widget::Widget(int a, int b)
    : a_{a},
      b_(b) {
  const char* sql = R"sql(SELECT "{" FROM t WHERE x = '}')sql";
  const char* text = "}{";
}

void Widget::Run() const ABSL_LOCKS_EXCLUDED(mutex_) {
  auto add = [&](int y) -> int {
    return y + 1;
  };
  switch (a_) {
    case 1: {
      break;
    }
  }
  Call(1, [this] {
    Done();
  });
}

Widget& Widget::operator=(Widget&& other) noexcept {
  return *this;
}

absl::StatusOr<int> Trailing(int v) noexcept {
  std::vector<int> values = {1, 2, 3};
  return values[v];
}
}  // namespace a::b
'''


class FunctionFinderTest(unittest.TestCase):
    def test_finds_functions_with_their_lines(self):
        found = list(size_limits.functions(SOURCE))
        spans = {(name, last - first + 1) for name, first, last in found}
        self.assertEqual(
            spans,
            {
                ("Free", 8),
                ("Widget::Widget", 6),
                ("Widget::Run", 13),
                ("<lambda>", 3),  # add
                ("<lambda>", 3),  # the callback
                ("Widget::operator=", 3),
                ("Trailing", 4),
            },
        )
        self.assertEqual(len(found), 7)

    def test_blanking_keeps_line_numbers(self):
        text = 'int x = 1; // {\n/* {\n} */ const char* s = "{";\n'
        blanked = size_limits.blank_non_code(text)
        self.assertEqual(blanked.count("\n"), text.count("\n"))
        self.assertNotIn("{", blanked)
        self.assertNotIn("}", blanked)


if __name__ == "__main__":
    unittest.main()
