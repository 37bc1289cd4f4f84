import os
import sys

import pytest
from hypothesis import settings

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

# Randomised everywhere, CI included (a derandomised profile replays one fixed set of examples and hid a
# failure): failing examples are kept in hypothesis' example database (.hypothesis/) and printed with their
# reproduction blob; once fixed they become explicit @example()s next to their test.
settings.register_profile("ci", max_examples=60, deadline=None, print_blob=True)
settings.register_profile("dev", max_examples=60, deadline=None)
settings.load_profile("ci" if os.environ.get("CI") else "dev")


@pytest.fixture(scope="session")
def seed_pivots():
    return ((0.0, 40.0), (10.0, 10.0), (20.0, 6.0), (30.0, 5.0), (60.0, 4.0))


@pytest.fixture(scope="session")
def mesh_file(tmp_path_factory):
    """A folder with two small mesh files (floor.ply, cube.stl) for scene-file tests."""
    import pyvista as pv

    d = tmp_path_factory.mktemp("mesh")
    pv.Plane(i_size=4, j_size=4, i_resolution=2, j_resolution=2, direction=(0, 1, 0)).save(str(d / "floor.ply"))
    pv.Cube(center=(0, 0.5, 1), x_length=1, y_length=1, z_length=1).save(str(d / "cube.stl"))
    return d


@pytest.fixture
def hang_guard():
    """Fail, instead of hanging, a test whose code blocks: ``with hang_guard(60): ...`` raises TimeoutError after
    60 s (an open() of a FIFO blocks until a writer comes; the alarm interrupts it)."""
    import contextlib
    import signal

    @contextlib.contextmanager
    def guard(seconds: int = 60):
        def hung(signum, frame):
            raise TimeoutError(f"still running after {seconds} s: something blocked (a FIFO opened?)")

        old = signal.signal(signal.SIGALRM, hung)
        signal.alarm(seconds)
        try:
            yield
        finally:
            signal.alarm(0)
            signal.signal(signal.SIGALRM, old)

    return guard
