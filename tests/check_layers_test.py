#!/usr/bin/env python3
"""CTest: the repository's includes follow its targets' links, and the checker does catch a wrong one."""
import pathlib
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parent.parent
CHECK = ROOT / "tools" / "check_layers.py"


def run(root):
    return subprocess.run([sys.executable, str(CHECK), str(root)], capture_output=True, text=True)


def main():
    ok = run(ROOT)
    print(ok.stdout, end="")
    assert ok.returncode == 0, "the repository breaks the layer order:\n" + ok.stdout

    with tempfile.TemporaryDirectory() as d:
        t = pathlib.Path(d)
        for folder in ("include/gshaptics/io", "src/io", "src/broadphase", "src/narrowphase",
                       "src/collision", "src/device", "src/servo"):
            (t / folder).mkdir(parents=True)
        # The build: core (io, broadphase, narrowphase, collision) <- device <- runtime (servo).
        (t / "CMakeLists.txt").write_text(
            "add_library(gshaptics_core src/error.cpp src/io/r.cpp src/broadphase/bvh.cpp\n"  # check_docs: ignore
            "  src/narrowphase/k.cpp src/collision/w.cpp)\n"  # check_docs: ignore
            "add_library(gshaptics_device src/device/d.cpp)\n"  # check_docs: ignore
            "target_link_libraries(gshaptics_device PUBLIC gshaptics_core)  # a comment (ignored)\n"
            "add_library(gshaptics_runtime src/servo/s.cpp)\n"  # check_docs: ignore
            "target_link_libraries(gshaptics_runtime PUBLIC gshaptics::device)\n")
        (t / "src/error.cpp").write_text("")
        (t / "src/io/r.cpp").write_text("")  # check_docs: ignore
        (t / "src/narrowphase/k.cpp").write_text("")  # check_docs: ignore
        (t / "src/collision/w.cpp").write_text("")  # check_docs: ignore
        (t / "include/gshaptics/io/reader.h").write_text(  # a file of the temporary tree (check_docs: ignore)
            '#include "gshaptics/collision/world.h"\n')
        (t / "src/broadphase/bvh.cpp").write_text('#include "gshaptics/narrowphase/k.h"\n'
                                                  '#include "gshaptics/error.h"\n')
        (t / "src/device/d.cpp").write_text('#include "gshaptics/io/reader.h"\n'  # check_docs: ignore
                                            '#include "gshaptics/servo/s.h"\n')
        (t / "src/servo/s.cpp").write_text('#include "gshaptics/device/d.h"\n'  # through two links: fine  # check_docs: ignore
                                           '#include "gshaptics/collision/w.h"\n'
                                           '#include "gshaptics/ros/r.h"\n')
        bad = run(t)
        assert bad.returncode == 1, bad.stdout
        assert "io (level 2) includes collision (level 4) inside one target" in bad.stdout, bad.stdout
        assert "broadphase (level 1) includes narrowphase" in bad.stdout, bad.stdout
        assert "device (gshaptics_device) includes servo (gshaptics_runtime), which its target does not link" in bad.stdout, bad.stdout
        assert "includes 'ros', a folder of no library target" in bad.stdout, bad.stdout
        assert "4 violations" in bad.stdout, bad.stdout
    print("1 passed, 0 failed")


if __name__ == "__main__":
    main()
