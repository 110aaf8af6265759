"""IBISCape ``other_sensors/gnss.csv``: ``#timestamp [ns], latitude [deg], longitude [deg],
altitude [m]``, comma separated, rows ending with a space (CARLA's GNSS sensor, WGS84)."""

from __future__ import annotations

import os

import numpy as np

from ibiscape_eval.core.errors import FormatError
from ibiscape_eval.core.gnss import GnssFixes

from ._poses import check_rows
from ._text import decimal_to_ns, parse_table, read_bytes, write_table
from .atomic import atomic_write

__all__ = ["GNSS_HEADER", "GnssFixes", "read_gnss", "write_gnss"]

#: Header exactly as the acquisition scripts' ``csv.writer`` writes it (without ``\r\n``).
GNSS_HEADER = "#timestamp [ns],latitude,longitude,altitude"
_EXPECTED = "4 columns (timestamp [ns], latitude [deg], longitude [deg], altitude [m])"


def read_gnss(path: str | os.PathLike[str]) -> GnssFixes:
    """Read an IBISCape ``gnss.csv``.

    Stamps (ns, integers or CARLA's ``%f`` floats) are parsed exactly.  NaN/inf rows are skipped
    and repeated stamps keep the first row (each with one warning naming the lines).

    Raises
    ------
    FormatError
        Wrong column count, non-numeric field, latitude/longitude out of range, decreasing
        stamps, empty or binary file; the message names the file and line.
    """
    data = read_bytes(path)
    tb = parse_table(path, data, nkeep=4, ncols_min=4, ncols_max=4, expected=_EXPECTED)
    del data  # the raw bytes are no longer needed: lower peak memory
    stamps = decimal_to_ns(path, tb, unit_exp=0)
    keep = check_rows(path, stamps, tb.finite, tb.lines, stacklevel=4)
    v = tb.values[keep]
    bad = (np.abs(v[:, 1]) > 90.0) | (np.abs(v[:, 2]) > 180.0)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise FormatError(path, f"latitude {v[i, 1]:g} / longitude {v[i, 2]:g} out of range "
                                "([-90, 90], [-180, 180] deg); check the column order",
                          line=int(tb.lines[keep[i]]))
    return GnssFixes(stamps[keep], v[:, 1], v[:, 2], v[:, 3])


def write_gnss(path: str | os.PathLike[str], fixes: GnssFixes) -> None:
    """Write ``fixes`` like the acquisition scripts (header, comma separated, rows ending in a
    space; stamps as integer ns with ``.000000``), atomically."""
    values = np.stack((fixes.lat_deg, fixes.lon_deg, fixes.alt_m), axis=1)
    with atomic_write(path, "wb") as f:
        f.write((GNSS_HEADER + "\r\n").encode())
        write_table(f, fixes.stamps_ns, values, stamp="ns_f", sep=",", row_end=" \n")
