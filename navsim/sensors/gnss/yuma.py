"""YUMA almanac files: :func:`load_yuma`, :func:`write_yuma` and the packaged almanac
(:func:`reference_almanac`, a GPS-like Walker 24/6/1; see ``navsim/data/almanac/README.md``).
Node angles are converted with IS-GPS-200's Earth rate (Table 20-IV).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ...earth import WGS84
from ...errors import ConfigError, file_value
from .constants import OMEGA_E_GPS, REFERENCE_ALMANAC, SECONDS_PER_WEEK
from .constellation import Constellation

_YUMA_KEYS = {
    "id": "id",
    "health": "health",
    "eccentricity": "eccentricity",
    "timeofapplicability": "toa",
    "orbitalinclination": "inclination",
    "rateofrightascen": "raan_rate",
    "sqrt(a)": "sqrt_a",
    "rightascenat": "raan0",  # "at Week" or "at TOA"
    "argumentofperigee": "arg_perigee",
    "meananom": "mean_anomaly",
    "af0": "af0",
    "af1": "af1",
    "week": "week",
}
_YUMA_REQUIRED = (
    "id",
    "eccentricity",
    "toa",
    "inclination",
    "raan_rate",
    "sqrt_a",
    "raan0",
    "arg_perigee",
    "mean_anomaly",
    "week",
)


def _yuma_key(label: str) -> str | None:
    compact = re.sub(r"\s+", "", label).lower()
    for prefix, key in _YUMA_KEYS.items():
        if compact.startswith(prefix):
            return key
    return None


def load_yuma(
    path: str | Path,
    *,
    epoch_offset_s: float = 0.0,
    healthy_only: bool = True,
    name: str | None = None,
) -> Constellation:
    """Read a YUMA almanac (the text format published by the US Coast Guard NAVCEN).

    Each record starts with a ``******** Week N almanac for PRN-xx ********`` line and
    holds ``label: value`` lines (ID, Health, Eccentricity, Time of Applicability(s),
    Orbital Inclination(rad), Rate of Right Ascen(r/s), SQRT(A) (m 1/2), Right Ascen at
    Week(rad), Argument of Perigee(rad), Mean Anom(rad), Af0(s), Af1(s/s), week).

    All records are brought to one reference epoch, the time of applicability of the
    first record, which is placed at scenario time ``epoch_offset_s``. The stored node
    angle is Omega_0 - Omega_e t_oa (IS-GPS-200 Table 20-IV, Omega_e of IS-GPS-200);
    records with another week/t_oa are propagated (mean anomaly and node) to the common
    epoch. Week numbers are used as written (the same 1024-week roll-over is assumed).

    Raises
    ------
    ConfigError
        On a malformed file; the message names the file and the line.
    """
    path = Path(path)
    try:
        lines = path.read_text(encoding="ascii", errors="replace").splitlines()
    except OSError as exc:
        raise ConfigError("almanac", "a readable YUMA file", str(path)) from exc
    source = str(path.name)
    records: list[dict[str, float]] = []
    starts: list[int] = []
    current: dict[str, float] | None = None
    for number, raw in enumerate(lines, start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("*"):
            current = {}
            records.append(current)
            starts.append(number)
            continue
        if current is None:
            raise ConfigError(
                f"line {number}", "a '******** Week N almanac for PRN-xx' header", file_value(line), source
            )
        label, sep, value = line.partition(":")
        key = _yuma_key(label) if sep else None
        if key is None:
            raise ConfigError(f"line {number}", "a YUMA 'label: value' line", file_value(line), source)
        try:
            number_value = float(value.strip())
        except ValueError:
            raise ConfigError(
                f"line {number}", "a number", file_value(value.strip()), source
            ) from None
        if not np.isfinite(number_value):
            raise ConfigError(f"line {number}", "a finite number", file_value(value), source)
        if key in current:
            raise ConfigError(f"line {number}", "one value of each label per record", file_value(line), source)
        current[key] = number_value
    if not records:
        raise ConfigError("almanac", "at least one YUMA record", str(path.name), source)
    for rec, start in zip(records, starts):
        missing = [k for k in _YUMA_REQUIRED if k not in rec]
        if missing:
            raise ConfigError(
                f"record at line {start}", f"fields {missing} to be present", sorted(rec), source
            )
        if not 0.0 <= rec["eccentricity"] < 1.0 or rec["sqrt_a"] <= 0.0:
            raise ConfigError(
                f"record at line {start}",
                "0 <= Eccentricity < 1 and SQRT(A) > 0",
                (rec["eccentricity"], rec["sqrt_a"]),
                source,
            )
    if healthy_only:
        records = [r for r in records if r.get("health", 0.0) == 0.0]
        if not records:
            raise ConfigError("almanac", "at least one healthy satellite", str(path.name), source)
    gm = WGS84.gm
    week = np.array([r["week"] for r in records])
    toa = np.array([r["toa"] for r in records])
    t_abs = week * SECONDS_PER_WEEK + toa
    shift = t_abs[0] - t_abs  # propagate each record to the first record's epoch
    a = np.array([r["sqrt_a"] for r in records]) ** 2
    raan_rate = np.array([r["raan_rate"] for r in records])
    n = np.sqrt(gm / a**3)
    # IS-GPS-200: Omega_k = Omega_0 + (Omega_dot - Omega_e) t_k - Omega_e t_oa
    node = np.array([r["raan0"] for r in records]) - OMEGA_E_GPS * toa
    node = node + (raan_rate - OMEGA_E_GPS) * shift
    mean_anomaly = np.array([r["mean_anomaly"] for r in records]) + n * shift
    prn = np.array([int(round(r["id"])) for r in records])
    return Constellation(
        name=name or path.stem,
        prn=prn,
        semi_major_axis_m=a,
        eccentricity=np.array([r["eccentricity"] for r in records]),
        inclination_rad=np.array([r["inclination"] for r in records]),
        raan_rad=np.angle(np.exp(1j * node)),
        arg_perigee_rad=np.array([r["arg_perigee"] for r in records]),
        mean_anomaly_rad=np.angle(np.exp(1j * mean_anomaly)),
        raan_rate_rps=raan_rate,
        epoch_offset_s=epoch_offset_s,
    )


def write_yuma(
    constellation: Constellation, path: str | Path, *, week: int = 0, toa_s: float = 0.0
) -> None:
    """Write ``constellation`` as a YUMA almanac with time of applicability ``toa_s``.

    The reference epoch of the constellation becomes (week, toa_s); satellite clock terms
    are written as zero and every satellite as healthy. :func:`load_yuma` reads it back
    (to the printed precision, about 10 significant digits).
    """
    c = constellation
    node0 = np.angle(np.exp(1j * (c.raan_rad + OMEGA_E_GPS * toa_s)))
    out = []
    for j in range(c.n_satellites):
        prn = int(c.prn[j])
        out += [
            f"******** Week {week} almanac for PRN-{prn:02d} ********",
            f"{'ID:':<28}{prn:02d}",
            f"{'Health:':<28}000",
            f"{'Eccentricity:':<28}{c.eccentricity[j]:.10E}",
            f"{'Time of Applicability(s):':<28}{toa_s:.4f}",
            f"{'Orbital Inclination(rad):':<28}{c.inclination_rad[j]:.10f}",
            f"{'Rate of Right Ascen(r/s):':<28}{c.raan_rate_rps[j]:.10E}",
            f"{'SQRT(A)  (m 1/2):':<28}{np.sqrt(c.semi_major_axis_m[j]):.6f}",
            f"{'Right Ascen at Week(rad):':<28}{node0[j]:.10E}",
            f"{'Argument of Perigee(rad):':<28}{c.arg_perigee_rad[j]:.10E}",
            f"{'Mean Anom(rad):':<28}{c.mean_anomaly_rad[j]:.10E}",
            f"{'Af0(s):':<28}{0.0:.10E}",
            f"{'Af1(s/s):':<28}{0.0:.10E}",
            f"{'week:':<28}{week}",
            "",
        ]
    from ...io import write_text_atomic

    write_text_atomic(path, "\n".join(out), encoding="ascii")


def reference_almanac(*, epoch_offset_s: float = 0.0) -> Constellation:
    """The packaged YUMA almanac: a GPS-like Walker 24/6/1 with small eccentricities.

    See ``navsim/data/almanac/README.md`` for how it was generated (no real almanac).
    """
    from importlib.resources import as_file, files

    resource = files("navsim") / "data" / "almanac" / REFERENCE_ALMANAC
    with as_file(resource) as path:
        return load_yuma(path, epoch_offset_s=epoch_offset_s, name="gps-walker-almanac")
