"""Typed step results: ``to_dict()`` / ``from_dict()`` round trips, key for key and in order."""

from __future__ import annotations

import json

import pytest

from ibiscape_eval.batch import canonical_json
from ibiscape_eval.benchmark import BenchmarkResult
from ibiscape_eval.benchmark.results import (
    STEP_VALUES,
    BenchmarkSteps,
    CameraCalibrationResult,
    CameraError,
    EvaluationScores,
    HotPixelsResult,
    ImuCameraError,
    ImuCameraResult,
    ImuNoiseResult,
    NoiseRow,
    PairError,
    StepRecord,
    SuiteSequence,
    VioResult,
)

VALUES = [
    SuiteSequence({"frames": 61, "name": "SVI_slam_clear_1", "weather_averages": {"rain": 0.0}}),
    CameraCalibrationResult(
        "SVI_calib_1", "aprilgrid", "pinhole-radtan",
        (CameraError("rgbL", 0.5, -0.25, 0.125, 1.0, 0.001, 160.5, 160.0),
         CameraError("rgbR", -0.5, 0.25, -0.125, -1.0, 0.002, 159.5, 160.0)),
        (PairError("rgbL", "rgbR", 1.5, 0.5, 0.01),), 0.3, 18, {"rgbL": "frames"}),
    CameraCalibrationResult("SVI_calib_2", None, "pinhole-radtan", (), (), None, None, {}),
    ImuCameraResult("SVI_calib_1", (ImuCameraError("rgbL", 0.1, 2.0, 0.5, 12.3, 12.8, None),),
                    True, ("weak yaw",), "calibrate_sequence"),
    ImuNoiseResult("IMU_calib_1", 360000, 0.5, 200.0,
                   (NoiseRow("gyroscope_noise_density", 1e-4, 1.1e-4, 10.0),
                    NoiseRow("gyroscope_random_walk", 0.0, None, None))),
    HotPixelsResult("ESVI_slam_dyn_1", "davisL", 12345, 3, 4, 0.05, 1.0, 0.75),
    VioResult("SVI_slam_clear_1", {"failures": [], "frames": 61}, 61, "0 0 0 0 0 0 0 1\n"),
    VioResult("SVI_slam_clear_1", {"frames": 61}, 61),
    EvaluationScores(0.12, 0.03, 0.4, 58),
]


@pytest.mark.parametrize("value", VALUES, ids=lambda v: type(v).__name__)
def test_every_value_round_trips_through_json(value) -> None:
    doc = value.to_dict()
    back = type(value).from_dict(json.loads(json.dumps(doc)))
    assert back == value
    assert json.dumps(back.to_dict()) == json.dumps(doc)  # same keys in the same order


@pytest.mark.parametrize("value", [v for v in VALUES if type(v) is not EvaluationScores],
                         ids=lambda v: type(v).__name__)
def test_a_job_value_reads_back_as_its_canonical_json(value) -> None:
    # a job's value arrives through canonical_json (sorted keys): writing it back changes nothing
    doc = json.loads(canonical_json(value.to_dict()))
    assert json.dumps(type(value).from_dict(doc).to_dict()) == json.dumps(doc)


def test_renamed_fields_and_omitted_estimate() -> None:
    assert PairError("a", "b", 1.0, 2.0, 3.0).to_dict()["from"] == "a"
    assert "estimate_tum" not in VioResult("s", {}, 0).to_dict()


def test_a_whole_result_round_trips() -> None:
    recs = {name: (StepRecord("k", "k", "ok", None, 1.5, False,
                              next(v for v in VALUES if isinstance(v, cls))),
                   StepRecord("f", "f", "failed", "ValueError: x", 0.0, True, None))
            for name, cls in STEP_VALUES.items()}
    steps = BenchmarkSteps(**recs)
    res = BenchmarkResult("out", "out/suite", 0.002, steps, [{"step": "vio", "sequence": "R",
                                                             "reason": "no pair"}],
                          {"markdown": "| x |"}, {"suite": 1.0, "vio": 2.0})
    doc = json.loads(json.dumps(res.to_dict()))
    back = BenchmarkResult.from_dict(doc)
    assert back == res and back.to_dict() == doc
    assert list(doc["steps"]) == list(STEP_VALUES)
    assert back.n_failed == len(STEP_VALUES) and back.steps.vio[0].value == recs["vio"][0].value


def test_a_document_of_another_shape_is_refused_naming_the_keys() -> None:
    from ibiscape_eval.core.errors import IbiscapeError

    doc = HotPixelsResult("s", "davisL", 1, 0, 0, None, None, None).to_dict()
    del doc["n_events"]
    with pytest.raises(IbiscapeError, match="HotPixelsResult: no n_events"):
        HotPixelsResult.from_dict(doc)
