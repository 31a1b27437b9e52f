"""The touch table: every column an array of the table's length once made."""

import numpy as np

from fruitcli.sensing.detection.model_fit import FIT_MODEL, FIT_NONE
from fruitcli.sensing.detection.touch_table import FIELDS, HOVER, TOUCH, TouchTable


def located(n: int, **columns) -> TouchTable:
    """A table of n touches with the columns every detection path gives."""
    return TouchTable.make(
        np.arange(n),
        np.zeros(n, np.int64),
        np.linspace(0, 1, n),
        np.linspace(2, 3, n),
        np.arange(3.0 * n).reshape(n, 3),
        np.full(n, 40.0),
        **columns,
    )


def test_columns_not_given_are_nan_touch_and_not_fitted():
    t = located(3)
    for name in ("height_mm", "height_err_mm", "strength", "size_mm", "pos_err_mm", "residual"):
        assert getattr(t, name).shape == (3,) and np.isnan(getattr(t, name)).all()
    assert t.kind.dtype == np.int8 and (t.kind == TOUCH).all()
    assert t.fit.dtype == np.int8 and (t.fit == FIT_NONE).all()


def test_columns_given_are_kept_and_rows_keep_every_column():
    kind = np.array([TOUCH, HOVER, TOUCH], np.int8)
    fit = np.array([FIT_MODEL, FIT_NONE, FIT_MODEL], np.int8)
    t = located(3, height_mm=np.array([0.0, 2.5, 0.5]), kind=kind, fit=fit)
    assert t.kind is kind and t.fit is fit
    touches = t.touches_only()
    assert len(touches) == 2
    np.testing.assert_array_equal(touches.height_mm, [0.0, 0.5])
    np.testing.assert_array_equal(touches.frame, [0, 2])
    assert all(len(getattr(touches, f)) == 2 for f in FIELDS)


def test_concat_of_none_is_an_empty_table_of_every_column():
    empty = TouchTable.concat([])
    assert len(empty) == 0 and all(len(getattr(empty, f)) == 0 for f in FIELDS)
    both = TouchTable.concat([located(2), empty, located(1)])
    assert len(both) == 3 and all(len(getattr(both, f)) == 3 for f in FIELDS)
    assert both.xyz_mm.shape == (3, 3)
