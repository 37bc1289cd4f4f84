"""A render can be cancelled between chunks of work (renderers.registry.render(cancel=...)): the live window's
Escape (issue 26, item 3). A cancelled render raises RenderCancelled after the hook said so, without finishing;
a render that is never cancelled gives the same image as one without the hook (smaller chunks, same pixels).
On the GPU backend the hook is asked before every compute dispatch, and a cancelled frame leaves the device
usable: the next render gives the same image."""

import numpy as np
import pytest

from renderers.plugin_types import RenderCancelled
from renderers.registry import render


@pytest.mark.parametrize("renderer, params, backend", [("gt", {"spp": 16}, "cpu"), ("lafr", {"delta": 2.0}, "cpu"),
                                                       ("gt", {"spp": 64}, "gpu"), ("lafr", {"delta": 2.0}, "gpu")])
def test_a_render_stops_when_its_cancel_hook_says_so(renderer, params, backend):
    asked = []

    def cancel():
        asked.append(1)
        return len(asked) >= 3

    with pytest.raises(RenderCancelled):
        render("cornell", renderer, params, 96, 54, backend=backend, cancel=cancel)
    assert len(asked) == 3  # it stopped at the third question, not at the end of the render

    calls = []
    plain, _ = render("cornell", renderer, params, 96, 54, backend=backend)
    hooked, _ = render("cornell", renderer, params, 96, 54, backend=backend,
                       cancel=lambda: calls.append(1) and False)
    assert len(calls) > 3  # asked between chunks all through the render
    assert np.array_equal(plain, hooked)
