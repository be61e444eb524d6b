import os

import pytest

SCENES = os.environ.get("GSHAPTICS_SCENES_DIR",
                        os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "data", "scenes"))
DATA = os.environ.get("GSHAPTICS_DATA_DIR", os.path.join(os.path.dirname(__file__), "..", "..", "data"))


@pytest.fixture(scope="session")
def scenes_dir():
    return SCENES


@pytest.fixture(scope="session")
def data_dir():
    return DATA
