"""A render can be cancelled between chunks of work (renderers.registry.render(cancel=...)): the live window's
Escape (issue 26, item 3). A cancelled render raises RenderCancelled after the hook said so, without finishing;
a render that is never cancelled gives the same image as one without the hook (smaller chunks, same pixels)."""

import numpy as np
import pytest

from renderers.plugin_types import RenderCancelled
from renderers.registry import render


@pytest.mark.parametrize("renderer, params", [("gt", {"spp": 16}), ("lafr", {"delta": 2.0})])
def test_a_render_stops_when_its_cancel_hook_says_so(renderer, params):
    asked = []

    def cancel():
        asked.append(1)
        return len(asked) >= 3

    with pytest.raises(RenderCancelled):
        render("cornell", renderer, params, 96, 54, cancel=cancel)
    assert len(asked) == 3  # it stopped at the third question, not at the end of the render

    calls = []
    plain, _ = render("cornell", renderer, params, 96, 54)
    hooked, _ = render("cornell", renderer, params, 96, 54, cancel=lambda: calls.append(1) and False)
    assert len(calls) > 3  # asked between chunks all through the render
    assert np.array_equal(plain, hooked)
