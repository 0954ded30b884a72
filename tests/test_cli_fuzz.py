"""A CLI fuzz test: malformed tables, model specs and boat configs through every command.

Hypothesis breaks a small valid table (cells that are not numbers, inf, positions off the globe or
swapped, lost or repeated columns, ragged rows, a byte-order mark, other encodings, random bytes),
writes malformed specs and configs, and runs the commands in-process through
``forcemap.host.cli.main``. Every run must exit 0 or 2, print no traceback, and leave every input
file byte for byte as it was.

The model fits use cheap specs (no 2-D GP over position) and ``report`` runs only on tables that
fail to load, so the whole test stays well under a minute; the full fits are tested elsewhere.
"""

from __future__ import annotations

import contextlib
import csv
import functools
import hashlib
import io
import tempfile
from pathlib import Path

from forcemap.host.cli import main
from forcemap.host.errors import CliError
from forcemap.host.workbench.survey.table import load_survey
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench.synth_survey import make_survey

COLUMNS = ["t", "lat", "lon", "depth", "water_temp", "current_speed", "heading"]
JUNK = ["", "1,5", "inf", "-inf", "nan", "deep", "1e400", "200", "-91", "0", " ", "True", "0x1F",
        "12abc", "--", "\u00e9", "1.5.2"]  # fmt: skip
TERMS = ["const", "linear(depth)", "power(depth)", "cos(heading)", "gp(depth, rbf)", "gp(t, matern12)",
         "gp(depth, matern99)", "gp()", "linear(depth, t)", "user(depth, nosuchmodule:f)", "user(depth)",
         "depth", "heading", "gp(heading, periodic)", "salinity", "gp(depth + t)", "cos(depth)",
         "gp(position, depth, t)", "((", "5"]  # fmt: skip
GOOD_SPEC = b'terms = ["const", "gp(t, matern12)"]\n'  # cheap: the table is what is fuzzed
SETTINGS = settings(
    max_examples=25,
    deadline=None,
    derandomize=True,  # the same examples on every run: CI fails or passes for a reason
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)


@functools.cache
def base_rows() -> tuple[tuple[str, ...], ...]:
    """A valid 40-row table with a few columns (a fresh synthetic river, once per session)."""
    with tempfile.TemporaryDirectory() as d:
        src = make_survey("river", ["depth_current"], 3, 60.0, d)
        with src.open() as f:
            rows = list(csv.reader(f))
    idx = [rows[0].index(c) for c in COLUMNS]
    return tuple(tuple(r[i] for i in idx) for r in rows[:41])


def _mostly(draw, usual: bytes, others: list[bytes], max_binary: int) -> bytes:
    """`usual` half the time, else one of `others`, or random bytes one time in ten."""
    pick = draw(st.integers(0, 9))
    if pick == 0:
        return draw(st.binary(max_size=max_binary))
    if pick < 5:
        return usual
    return draw(st.sampled_from(others))


ALL_BREAKS = ("cell", "column", "drop", "dup", "ragged", "truncate", "swap")


@st.composite
def csv_text(draw, breaks: tuple[str, ...] = ALL_BREAKS) -> str:
    """The base table with its cells, columns and rows broken (still CSV text)."""
    rows = [list(r) for r in base_rows()]
    header, body = rows[0], rows[1:]
    for _ in range(draw(st.integers(0, 6))):
        kind = draw(st.sampled_from(breaks))
        if not body or not header:
            break
        if kind == "cell":
            r, c = draw(st.integers(0, len(body) - 1)), draw(st.integers(0, len(header) - 1))
            body[r][c] = draw(st.sampled_from(JUNK) | st.text(max_size=6))
        elif kind == "column":
            c, v = draw(st.integers(0, len(header) - 1)), draw(st.sampled_from(JUNK))
            for r in body:
                r[c] = v
        elif kind == "drop" and len(header) > 1:
            c = draw(st.integers(0, len(header) - 1))
            del header[c]
            for r in body:
                del r[c]
        elif kind == "dup":
            header[draw(st.integers(0, len(header) - 1))] = draw(st.sampled_from(header))
        elif kind == "ragged":
            body[draw(st.integers(0, len(body) - 1))].append("1")
        elif kind == "truncate":
            body = body[: draw(st.integers(0, len(body)))]
        elif kind == "swap" and {"lat", "lon"} <= set(header):
            i, j = header.index("lat"), header.index("lon")
            for r in body[draw(st.integers(0, len(body))) :]:
                r[i], r[j] = r[j], r[i]
    text = io.StringIO()
    csv.writer(text).writerows([header, *body])
    return text.getvalue()


@st.composite
def table_files(draw) -> bytes:
    """A broken table, in another encoding, cut short, empty, or random bytes."""
    text = draw(csv_text())
    encoding = draw(st.sampled_from(["utf-8", "utf-8-sig", "latin-1", "utf-16"]))
    data = text.encode(encoding, errors="replace")
    return _mostly(draw, data, [b"", data[: len(data) // 2]], 200)


@st.composite
def specs(draw) -> bytes:
    terms = draw(st.lists(st.sampled_from(TERMS), min_size=0, max_size=3))
    target = draw(
        st.sampled_from(["", 'target = "water_temp"\n', "target = 3\n", 'target = "nope"\n'])
    )
    body = draw(
        st.sampled_from(
            [
                "terms = [" + ", ".join(f'"{t}"' for t in terms) + "]\n",
                "terms = 5\n",
                '[[term]]\nkind = "gp"\ninputs = ["depth"]\nkernel = "bogus"\n',
                '[[term]]\nkind = "linear"\ninputs = ["water_temp"]\n',
                '[[term]]\nkind = "user"\ninputs = ["depth"]\n',
                "terms = [\n",
            ]
        )
    )
    return _mostly(draw, GOOD_SPEC, [(target + body).encode()] * 4, 60)


@st.composite
def configs(draw) -> bytes:
    section = draw(
        st.sampled_from(["anemometer", "vane", "current", "depth", "sync", "compass", "nope"])
    )
    key = draw(st.sampled_from(["mps_per_hz", "vref", "adc_ref", "offset_deg", "estimator", "offset_m",
                                "mode", "variation_deg", "rate_window_s", "x"]))  # fmt: skip
    value = draw(
        st.sampled_from(["2.4", "3300", "-1", "nan", '"auto"', "true", "[1, 2]", "0.7", "{}"])
    )
    wheels = draw(st.sampled_from(["", "[[wheels]]\nangle_deg = 0.785\n" * 4, "wheels = 4\n"]))
    text = f"[{section}]\n{key} = {value}\n{wheels}"
    return _mostly(draw, b"", [text.encode()] * 4, 60)


def _nmea() -> bytes:
    """A few depth sentences: a valid capture for `import` to read with the fuzzed config."""

    def sentence(body: str) -> str:
        checksum = 0
        for ch in body:
            checksum ^= ord(ch)
        return f"${body}*{checksum:02X}\r\n"

    return "".join(
        sentence(f"SDDBT,{d:.1f},f,{d * 0.3048:.2f},M,{d / 6:.2f},F") for d in range(5, 25)
    ).encode()


def _run(argv: list[str]) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, err.getvalue()


def _sha(paths: list[Path]) -> dict[Path, str]:
    return {p: hashlib.sha256(p.read_bytes()).hexdigest() for p in paths}


def _loads(table: Path) -> bool:
    try:
        load_survey(table)
    except CliError:
        return False
    return True


def _check_commands(d: Path, inputs: list[Path], runs: list[list]) -> None:
    """Every run exits 0 or 2 with no traceback, and no input file changes."""
    before = _sha(inputs)
    for argv in runs:
        code, err = _run([str(a) for a in argv])
        assert code in (0, 2), (argv, err)
        assert "Traceback" not in err, (argv, err)
    assert _sha(inputs) == before


@SETTINGS
@given(
    text=csv_text(("cell", "cell", "column", "swap")),
    target=st.sampled_from(["water_temp", "depth", "current_speed"]),
)
def test_workbench_on_broken_cells(text, target):
    """Tables that mostly still load: the fits and diagnoses run on what is left."""
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        t, good = d / "survey.csv", d / "good.toml"
        t.write_text(text)
        good.write_bytes(GOOD_SPEC)
        runs = [
            ["fit", t, "--target", target, "--model", good, "--quiet", "--no-plots"],
            ["diagnose", t, "--target", target, "--model", good, "--quiet"],
            ["history", t],
        ]
        _check_commands(d, [t, good], runs)


@SETTINGS
@given(
    table=table_files(),
    suffix=st.sampled_from([".csv"] * 6 + [".parquet", ".mcap"]),
    spec=specs(),
    config=configs(),
    target=st.sampled_from(
        ["water_temp"] * 3 + ["depth"] * 2 + ["current_speed", "heading", "nope"]
    ),
    out_folder=st.booleans(),
)
def test_every_command_on_malformed_files(table, suffix, spec, config, target, out_folder):
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        t, s, c, n = d / f"survey{suffix}", d / "spec.toml", d / "boat.toml", d / "depth.nmea"
        good = d / "good.toml"
        t.write_bytes(table)
        s.write_bytes(spec)
        c.write_bytes(config)
        n.write_bytes(_nmea())
        good.write_bytes(GOOD_SPEC)
        inputs = [t, s, c, n, good]
        runs = [
            ["fit", t, "--target", target, "--model", good, "--quiet", "--no-plots"],
            ["fit", t, "--target", target, "--model", s, "--json", d / "out" / "f.json", "--quiet"],
            ["diagnose", t, "--target", target, "--model", s, "--quiet", "--json", d / "d.json"],
            ["history", t, "-o", d / "h.png"],
            ["export", t, "-o", d / "export.csv"],
            ["log", "info", t],
            ["import", n, "--boat", c, "-o", d / "imported"],
        ]
        if not _loads(t):  # the report refits every target: on a table that loads it takes a minute
            runs.append(["report", t, "-o", d / "r.html", "--quiet"])
        (d / "imported").mkdir()
        if out_folder:  # else the --json folder is missing: refused before the fit
            (d / "out").mkdir()
        _check_commands(d, inputs, runs)
