import os

import pytest

SCENES = os.environ.get("GSHAPTICS_SCENES_DIR",
                        os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "data", "scenes"))
DATA = os.environ.get("GSHAPTICS_DATA_DIR", os.path.join(os.path.dirname(__file__), "..", "..", "data"))


@pytest.fixture(scope="session")
def scenes_dir():
    """The real scenes; tests that need them skip, saying where to put them, when they are absent."""
    if not os.path.exists(os.path.join(SCENES, "donut.ply")):
        pytest.skip(f"real scenes not found in {SCENES}: put the scenes (donut.ply, ...) there or set "
                    "GSHAPTICS_SCENES_DIR")
    return SCENES


@pytest.fixture(scope="session")
def data_dir():
    return DATA
