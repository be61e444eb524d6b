#!/usr/bin/env python3
"""tools/check_doc_defaults.py: every option default the docs state is the CLI's, and the checker
finds a stated default that differs, in a small tree made for it.
Usage: check_doc_defaults_test.py GSHAPTICS_BINARY"""
import pathlib
import subprocess
import sys
import tempfile
import unittest

ROOT = pathlib.Path(__file__).resolve().parent.parent
TOOL = ROOT / "tools" / "check_doc_defaults.py"
BINARY = None


def run(root):
    return subprocess.run([sys.executable, str(TOOL), BINARY, str(root)], capture_output=True, text=True)


class CheckDocDefaults(unittest.TestCase):
    def test_the_docs_state_the_clis_defaults(self):
        p = run(ROOT)
        self.assertEqual(p.returncode, 0, p.stdout + p.stderr)
        self.assertRegex(p.stdout, r"[1-9]\d* stated defaults compared, 0 differ")

    def test_a_wrong_default_is_found(self):
        with tempfile.TemporaryDirectory() as d:
            t = pathlib.Path(d)
            (t / "docs").mkdir()
            (t / "README.md").write_text("proxy: --stiffness 999 (N/m) --f-max 30 (N)\n")
            (t / "docs" / "usage.md").write_text("--energy-bound on|off (default off)\n`--substeps 4`, the default\n")
            p = run(t)
            self.assertEqual(p.returncode, 1, p.stdout)
            self.assertIn("README.md:1: says --stiffness defaults to 999", p.stdout)
            self.assertIn("docs/usage.md:1: says --energy-bound defaults to off", p.stdout)
            self.assertNotIn("--f-max defaults", p.stdout)
            self.assertNotIn("--substeps defaults", p.stdout)
            self.assertIn("4 stated defaults compared, 2 differ", p.stdout)


if __name__ == "__main__":
    BINARY = sys.argv.pop(1)
    unittest.main(verbosity=2)
