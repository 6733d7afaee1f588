import gc

import numpy as np
import pytest
from hypothesis import settings

from chekhov.world import World

# Property tests draw the same examples on every run and every machine: a CI run can only fail
# where a local run fails too (no example database, derandomised).  Tests still set their own
# max_examples; the profile supplies what they do not.
settings.register_profile("chekhov", derandomize=True, database=None, deadline=None)
settings.load_profile("chekhov")


@pytest.fixture(scope="session")
def worlds() -> dict[str, World]:
    """One World per built-in scene, shared by the whole session (grids are built once)."""
    return {}


@pytest.fixture(scope="session")
def world_of(worlds):
    def get(name: str) -> World:
        if name not in worlds:
            worlds[name] = World.load(name)
        return worlds[name]
    return get


@pytest.fixture(autouse=True)
def _heap_unfrozen():
    """Warm-ups freeze the heap out of the garbage collector's way (``chekhov._heap``): for
    a process that plans for hours; in a test session, what one test froze is made
    collectable again after it, so that later tests' garbage cycles are not kept."""
    yield
    gc.unfreeze()


@pytest.fixture()
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


@pytest.fixture(scope="module")
def bench_dir(tmp_path_factory):
    """A directory of the test module's own, with CHEKHOV_CACHE (where generated case files
    go) inside it for as long as the module runs."""
    d = tmp_path_factory.mktemp("bench")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("CHEKHOV_CACHE", str(d / "cache"))
        yield d
