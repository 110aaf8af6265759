"""Notebook-friendly IMU results: short repr, HTML tables, to_dict, default axis names."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ibiscape_eval.core import IbiscapeError
from ibiscape_eval.imu import allan_deviation, fit_noise_model


def _model():  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(2)
    res = allan_deviation(rng.normal(size=(20_000, 6)) * 0.01, 100.0)
    return res, fit_noise_model(res)


def test_default_names_and_kalibr_without_arguments() -> None:
    res, model = _model()
    assert res.names == ("w_x", "w_y", "w_z", "a_x", "a_y", "a_z")
    assert model.kalibr() == model.kalibr(gyro=res.names[:3], accel=res.names[3:])
    assert model.kalibr_discrete().keys() == model.kalibr_discrete(res.names[:3],
                                                                   res.names[3:]).keys()


def test_kalibr_needs_names_for_other_axis_counts() -> None:
    rng = np.random.default_rng(3)
    res = allan_deviation(rng.normal(size=(5_000, 2)), 100.0)
    assert res.names == ("0", "1")
    with pytest.raises(IbiscapeError, match="name the gyro"):
        fit_noise_model(res).kalibr()


def test_reprs_are_short_and_to_dict_is_strict_json() -> None:
    res, model = _model()
    for obj in (res, model):
        r = repr(obj)
        assert len(r) < 1500 and "array(" not in r
        assert obj._repr_html_().startswith(("<table>", "<pre>"))
        json.dumps(obj.to_dict(), allow_nan=False)
    assert set(model.to_dict()["axes"]) == set(res.names)
