"""The calibration's thread map keeps the order of its items and raises what a worker raised."""

from __future__ import annotations

import threading

import pytest

from ibiscape_eval.calib._threads import thread_map


def test_results_in_item_order_from_several_threads():
    seen = set()

    def f(x):
        seen.add(threading.get_ident())
        return x * x

    assert thread_map(f, list(range(50)), 3) == [x * x for x in range(50)]
    assert thread_map(f, [4], 3) == [16]
    assert thread_map(f, [], 3) == []
    assert len(seen) >= 1


def test_a_worker_error_is_raised_in_the_caller():
    def f(x):
        if x == 7:
            raise ValueError("item 7")
        return x

    with pytest.raises(ValueError, match="item 7"):
        thread_map(f, list(range(20)), 2)
