#!/usr/bin/env python3
"""tools/check_docs.py: the repository's own references all resolve, and the checker finds each
kind of broken one in a small tree made for it."""
import pathlib
import subprocess
import sys
import tempfile
import unittest

ROOT = pathlib.Path(__file__).resolve().parent.parent
TOOL = ROOT / "tools" / "check_docs.py"


def run(root):
    return subprocess.run([sys.executable, str(TOOL), str(root)], capture_output=True, text=True)


class CheckDocs(unittest.TestCase):
    def test_the_repository_has_no_broken_reference(self):
        p = run(ROOT)
        self.assertEqual(p.returncode, 0, p.stdout + p.stderr)
        self.assertIn(", 0 broken references", p.stdout)

    def test_each_kind_of_broken_reference_is_found(self):
        with tempfile.TemporaryDirectory() as d:
            t = pathlib.Path(d)
            (t / "docs").mkdir()
            (t / "include").mkdir()
            (t / "docs" / "design.md").write_text("# notes\n\n## 1. Pipeline\n\n## 2. Frames\n")
            (t / "docs" / "usage.md").write_text("# Usage\n\n## Building\n")
            (t / "README.md").write_text(
                "[ok](docs/usage.md#building) [gone](docs/missing.md) [bad anchor](docs/usage.md#running)\n")
            (t / "include" / "a.h").write_text(
                "// see docs/design.md Sec. 2, docs/design.md Sec. 7 and tools/nothing.py\n"
                "// (DESIGN.md Sec. 4)\n")
            (t / "src").mkdir()
            (t / "tools").mkdir()
            (t / "cmake").mkdir()
            (t / "tools" / "plot_a.py").write_text("")
            (t / "tools" / "plot_b.py").write_text("")
            (t / "cmake" / "Install.cmake").write_text("install(FILES tools/plot_a.py DESTINATION share)\n")
            (t / "src" / "s.cpp").write_text('run(find_tool_script("plot_a.py"));\nrun(find_tool_script("plot_b.py"));\n')
            p = run(t)
            self.assertEqual(p.returncode, 1, p.stdout)
            out = p.stdout
            self.assertIn("README.md:1: link to docs/missing.md: no such file", out)
            self.assertIn("no heading '#running'", out)
            self.assertNotIn("#building", out)
            self.assertIn("cites docs/design.md Sec. 7", out)
            self.assertNotIn("Sec. 2,", out)
            self.assertIn("names tools/nothing.py", out)
            self.assertIn("cites DESIGN.md", out)
            self.assertIn("src/s.cpp:2: runs tools/plot_b.py, which cmake/Install.cmake does not install", out)
            self.assertNotIn("plot_a.py, which", out)
            self.assertIn(", 6 broken references", out)


if __name__ == "__main__":
    unittest.main(verbosity=2)
