"""The README's measured numbers come from a recorded file, never from typing.

``examples/demo.py`` writes what it measured (wall times, the benchmark's accuracies against the
truth) to ``demo-output/numbers.json``.  This script copies such a file to the recorded copy kept
in the repository (``benchmarks/measured/demo.json``) and rewrites every marked number of the
README from it::

    .venv/bin/python benchmarks/update_readme_numbers.py --from demo-output/numbers.json
    .venv/bin/python benchmarks/update_readme_numbers.py --check   # exit 1 if README disagrees

A marked number in README.md is an HTML comment pair (invisible when rendered) around the text::

    <!-- measured:demo.wall_min .0f -->17<!-- /measured -->

``demo.wall_min`` is a dotted path into the recorded file (list items by index), ``.0f`` a Python
format spec.  A value that is a two-number list ``[lo, hi]`` is written ``lo-hi`` (``lo`` alone
when both print the same).  ``tests/test_readme.py`` fails when a marked README number and the
recorded file disagree by more than their printed precision.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
RECORDED = ROOT / "benchmarks" / "measured" / "demo.json"

MARK = re.compile(r"<!-- measured:(?P<key>[\w.\[\]-]+)(?: (?P<fmt>[^\s>]+))? -->(?P<text>.*?)"
                  r"<!-- /measured -->", re.S)
# numbers as printed: a sign only where it cannot be the dash of a range ("0.32-0.41")
NUMBER = re.compile(r"(?<![\d.])[+−-]?\d+(?:\.\d+)?|\d+(?:\.\d+)?")


def lookup(doc: Any, key: str) -> Any:
    """``doc["a"]["b"][0]`` for ``"a.b.0"``; KeyError naming the key when it is missing."""
    cur = doc
    for part in key.split("."):
        if isinstance(cur, list) and part.lstrip("-").isdigit():
            cur = cur[int(part)]
        elif isinstance(cur, dict) and part in cur:
            cur = cur[part]
        else:
            raise KeyError(f"{key}: no {part!r} in the recorded numbers")
    return cur


def render(value: Any, fmt: str | None) -> str:
    """The text of a recorded value: a number, or ``lo-hi`` for a two-number list."""
    spec = fmt or "g"
    if isinstance(value, list) and len(value) == 2 and all(
            isinstance(v, int | float) for v in value):
        lo, hi = format(value[0], spec), format(value[1], spec)
        return lo if lo == hi else f"{lo}-{hi}"
    if isinstance(value, int | float) and not isinstance(value, bool):
        return format(value, spec)
    return str(value)


def numbers_in(text: str) -> list[float]:
    return [float(m.replace("−", "-")) for m in NUMBER.findall(text)]


def _decimals(text: str) -> int:
    return len(text.split(".", 1)[1]) if "." in text else 0


def rewrite(readme: str, recorded: dict[str, Any]) -> str:
    """``readme`` with every marked number replaced by the recorded value."""
    def sub(m: re.Match[str]) -> str:
        text = render(lookup(recorded, m.group("key")), m.group("fmt"))
        fmt = f" {m.group('fmt')}" if m.group("fmt") else ""
        return f"<!-- measured:{m.group('key')}{fmt} -->{text}<!-- /measured -->"

    return MARK.sub(sub, readme)


def check(readme: str, recorded: dict[str, Any]) -> list[str]:
    """Every marked README number that disagrees with the recorded value by more than half a unit
    of its last printed digit (one line per problem; empty when all agree)."""
    problems = []
    for m in MARK.finditer(readme):
        key, shown = m.group("key"), m.group("text")
        try:
            want_text = render(lookup(recorded, key), m.group("fmt"))
        except (KeyError, IndexError) as e:
            problems.append(f"{key}: {e}")
            continue
        if shown == want_text:
            continue
        got, want = numbers_in(shown), numbers_in(want_text)
        if len(got) != len(want):
            problems.append(f"{key}: README says {shown!r}, recorded {want_text!r}")
            continue
        for g, w, piece in zip(got, want, NUMBER.findall(shown), strict=True):
            tol = 0.5 * 10.0 ** -_decimals(piece) + 1e-12
            if not math.isclose(g, w, abs_tol=tol):
                problems.append(f"{key}: README says {shown!r}, recorded {want_text!r}")
                break
    return problems


def marked_keys(readme: str) -> list[str]:
    return [m.group("key") for m in MARK.finditer(readme)]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--from", dest="source", type=Path, default=None,
                    help="a numbers.json the demo wrote: becomes the recorded copy")
    ap.add_argument("--check", action="store_true",
                    help="change nothing; exit 1 if a README number disagrees")
    args = ap.parse_args()
    if args.source is not None:
        doc = json.loads(args.source.read_text(encoding="utf-8"))
        if not doc.get("complete"):
            print(f"note: {args.source} is from a partial demo run (steps {doc.get('steps')}); "
                  "numbers it lacks keep their recorded values", file=sys.stderr)
            old = json.loads(RECORDED.read_text(encoding="utf-8")) if RECORDED.is_file() else {}
            doc = _merge(old, doc)
        if not args.check:
            RECORDED.parent.mkdir(parents=True, exist_ok=True)
            tmp = RECORDED.with_suffix(".json.tmp")
            tmp.write_text(json.dumps(doc, indent=1, allow_nan=False) + "\n", encoding="utf-8")
            tmp.replace(RECORDED)
    recorded = json.loads(RECORDED.read_text(encoding="utf-8"))
    readme = README.read_text(encoding="utf-8")
    if args.check:
        problems = check(readme, recorded)
        for p in problems:
            print(p)
        return 1 if problems else 0
    try:
        new = rewrite(readme, recorded)
    except (KeyError, IndexError) as e:
        print(f"error: {RECORDED}: {e}; README.md left unchanged", file=sys.stderr)
        return 2
    if new != readme:
        tmp = README.with_suffix(".md.tmp")
        tmp.write_text(new, encoding="utf-8")
        tmp.replace(README)
    print(f"{len(marked_keys(new))} marked numbers in {README.name} from {RECORDED}")
    return 0


def _merge(old: Any, new: Any) -> Any:
    """``new`` over ``old``, dictionaries merged key by key."""
    if isinstance(old, dict) and isinstance(new, dict):
        return {**old, **{k: _merge(old.get(k), v) for k, v in new.items()}}
    return new


if __name__ == "__main__":
    sys.exit(main())
