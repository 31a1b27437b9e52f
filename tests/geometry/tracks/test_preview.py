"""preview.png: nothing drawn is cut by the picture's edges."""

from __future__ import annotations

import numpy as np

from fruitcli.geometry.tracks.preview import write_preview


def test_preview_has_a_blank_margin_on_every_side(tmp_path):
    """A label cut off by the edge (the x label was) leaves ink in the outermost rows."""
    import matplotlib.image

    x, y = np.meshgrid(np.linspace(-90, 50, 15), np.linspace(-60, 60, 13), indexing="ij")
    v = np.column_stack([x.ravel(), y.ravel(), 5 * np.cos(x.ravel() / 40)])
    idx = np.arange(15 * 13).reshape(15, 13)
    a, b, c, d = (
        idx[:-1, :-1].ravel(),
        idx[1:, :-1].ravel(),
        idx[1:, 1:].ravel(),
        idx[:-1, 1:].ravel(),
    )
    f = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    curves = [v[idx[i]] for i in range(0, 15, 3)]
    taxels = v[idx[::3, ::3].ravel()]
    path = tmp_path / "preview.png"
    write_preview(path, v, f, curves, taxels, title="test piece")
    img = matplotlib.image.imread(path)[:, :, :3]
    ink = img.min(axis=2) < 0.9
    assert ink.any()
    assert not ink[:3].any() and not ink[-3:].any()
    assert not ink[:, :3].any() and not ink[:, -3:].any()
