"""The pipeline contract: synthetic instrument bytes in, timed and compensated topics out."""

from __future__ import annotations

import math
import random

import jsonschema
import pytest
from forcemap.host.fuse.pipeline import HOLD_S, ListSink, NullSink, Pipeline
from forcemap.host.log.messages import SAMPLE_COLUMNS, record_type
from forcemap.protocol import wire

from bench.synth_streams import T0, generate, truth_wind_current


@pytest.fixture(scope="module")
def survey():
    events, truth = generate(240, seed=3)
    sink = ListSink()
    pipe = Pipeline(sink=sink)
    for e in events:
        pipe.feed(*e)
    pipe.close()
    return events, truth, sink, pipe


def test_topics_metadata_and_counts(survey):
    events, _, sink, pipe = survey
    topics = {t for t, _, _ in sink.messages}
    for t in (
        "/bridge/frame",
        "/bridge/hello",
        "/bridge/status",
        "/nmea/sentence",
        "/mavlink/ATTITUDE",
        "/mavlink/GLOBAL_POSITION_INT",
        "/mavlink/SYSTEM_TIME",
        "/boat/state",
        "/wind/apparent",
        "/wind/true",
        "/current",
        "/depth",
        "/fix",
        "/timesync",
        "/diagnostics",
        "/samples",
    ):
        assert t in topics, t
    assert {n for n, _ in sink.meta} == {"calibration", "config", "hello", "columns", "sources"}
    columns = [m for n, m in sink.meta if n == "columns"][-1]
    assert columns["wind_speed"].startswith("bridge anemometer+vane + mavlink ATTITUDE")
    assert columns["current_speed"].startswith("bridge paddle wheels")
    assert columns["depth"] == "depth SDDPT" and columns["lat"] == "mavlink GLOBAL_POSITION_INT"
    c = pipe.counters()
    assert c["bridge"]["samples"] == 240 * 4 == len(sink.topic("/samples"))
    assert c["bridge"]["rejected"]["total"] == 0 and c["bridge"]["lost_frames"] == 0
    assert c["nmea"]["accepted"] == 3 * 240 and c["nmea"]["rejected"] == 0
    assert c["mavlink"]["bad_crc"] == 0 and c["mavlink"]["vehicle"] == [1, 1]
    assert c["samples"]["pending"] == 0 and c["samples"]["without_state"] <= 1
    assert c["last_fix"] is not None and not c["errors"]


def test_samples_are_table_rows(survey):
    rows = survey[2].topic("/samples")
    for r in rows:
        assert tuple(r) == SAMPLE_COLUMNS
    r = rows[len(rows) // 2]
    from_elsewhere = {"stw", "current_speed_stw", "current_dir_stw"}
    from_elsewhere |= {"wind_speed_instrument", "wind_dir_instrument"}
    # no beam angle in the boat file (no tilt correction, no raw reading kept); no bottom lost
    from_elsewhere |= {"depth_raw", "bottom_lost"}
    assert all(r[k] is not None for k in SAMPLE_COLUMNS if k not in from_elsewhere), r
    assert all(r[k] is None for k in from_elsewhere), r  # empty, not zero: no log, no wind sensor
    assert 0 <= r["heading"] < 360 and 0 <= r["wind_dir"] < 360 and 0 <= r["current_dir"] < 360
    assert (
        r["depth"] == pytest.approx(3.0, abs=2.5)
        and r["water_temp"] == 18.5
        and r["throttle"] == 40.0
    )


def test_sample_times_are_utc_from_the_device_clock(survey):
    """The bridge clock runs 40 ppm fast from another epoch; samples still land on true time."""
    rows = survey[2].topic("/samples")
    errs = [abs(r["t"] - (T0 + 0.25 * (i + 1))) for i, r in enumerate(rows)]
    assert max(errs[40:]) < 0.005  # after the first 10 s of fitting
    assert max(errs) < 0.02
    mapping = [m for m in survey[2].topic("/timesync") if m["source"] == "bridge"][-1]
    assert mapping["drift_ppm"] == pytest.approx(-40.0, abs=5.0)


def test_true_wind_and_current_against_truth(survey):
    """Per-sample bounds from the sensors (docs/COMPENSATION.md): the vane's 22.5 deg steps
    dominate wind (<= 2 sin(5.9 deg) |R| + 0.15 m/s); wheels resolve flow from ahead."""
    _, truth, sink, _ = survey
    n = 0
    for r in sink.topic("/samples")[8:]:
        tr = truth_wind_current(truth, r["t"] - T0)
        aws = r["app_wind_speed"]
        werr = math.hypot(r["wind_east"] - tr["wind_east"], r["wind_north"] - tr["wind_north"])
        assert werr <= 2 * math.sin(math.radians(5.9)) * aws + 0.15
        cerr = math.hypot(
            r["current_east"] - tr["current_east"], r["current_north"] - tr["current_north"]
        )
        assert cerr <= 0.1
        n += 1
    assert n > 900


def test_every_message_matches_its_schema(survey):
    """Every message of the run against the schema of the topic's record type."""
    sink = survey[2]
    validators: dict[str, jsonschema.Validator] = {}
    for topic, log_ns, msg in sink.messages:
        if topic not in validators:
            rtype = record_type(topic)
            assert rtype is not None, topic
            schema = rtype.json_schema()
            cls = jsonschema.validators.validator_for(schema)
            cls.check_schema(schema)
            validators[topic] = cls(schema)
        validators[topic].validate(msg)
        assert isinstance(log_ns, int) and log_ns > 1_700_000_000 * 10**9
    assert record_type("/fix").NAME == "foxglove.LocationFix"
    fix = sink.topic("/fix")[0]
    assert set(fix) == {
        "timestamp",
        "frame_id",
        "latitude",
        "longitude",
        "altitude",
        "position_covariance",
        "position_covariance_type",
    }
    assert len(fix["position_covariance"]) == 9


def _rows(events, chunker, sync="interpolate"):
    sink = ListSink()
    pipe = Pipeline(sink=sink, sync=sync)
    for src, mono, wall, data in events:
        for piece in chunker(data):
            pipe.feed(src, mono, wall, piece)
    pipe.close()
    return sink.topic("/samples"), pipe


def test_chunking_does_not_change_the_result():
    events, _ = generate(30, seed=4)
    whole, _ = _rows(events, lambda d: [d])
    rng = random.Random(9)

    def bits(d):
        out, i = [], 0
        while i < len(d):
            n = rng.randint(1, 17)
            out.append(d[i : i + n])
            i += n
        return out

    assert _rows(events, bits)[0] == whole
    assert len(whole) == 120


def test_garbage_on_every_port_is_counted_never_raised():
    events, _ = generate(20, seed=5)
    rng = random.Random(11)
    sink = NullSink()
    pipe = Pipeline(sink=sink)
    noise = 0
    for src, mono, wall, data in events:
        pipe.feed(src, mono, wall, data)
        if rng.random() < 0.2:
            junk = bytes(rng.randrange(256) for _ in range(rng.randint(1, 64)))
            pipe.feed(src, mono, wall, junk)
            noise += 1
    pipe.feed("nonsense", 0, 0, b"xx")
    pipe.close()
    c = pipe.counters()
    assert noise > 20
    assert c["bridge"]["rejected"]["total"] > 0
    assert c["nmea"]["rejected"] > 0
    assert c["mavlink"]["junk_bytes"] > 0 or c["mavlink"]["bad_crc"] > 0
    assert c["errors"] == {"unknown_source": 1}
    assert c["bridge"]["samples"] >= 70  # frames hit by junk are lost, the rest decode


def test_gap_drops_partial_frames_and_is_logged():
    sink = ListSink()
    pipe = Pipeline(sink=sink)
    frame = wire.encode(wire.STATUS, 1, 0, 1000, wire.pack_status([1, 0, 0, 0, 0, 0]))
    pipe.feed("bridge", 1, int(T0 * 1e9), frame[:10])
    pipe.gap("bridge", int(T0 * 1e9), "port closed")
    pipe.feed("bridge", 2, int(T0 * 1e9), frame[10:])
    pipe.feed("depth", 2, int(T0 * 1e9), b"$SDDPT,1.0")
    pipe.gap("depth", int(T0 * 1e9), "reconnected")
    pipe.feed("depth", 3, int(T0 * 1e9), b",0.0,*00\r\n")
    pipe.gap("mavlink", int(T0 * 1e9), "reconnected")
    assert not sink.topic("/bridge/status")
    events = [m["event"] for m in sink.topic("/diagnostics") if "event" in m]
    assert [e["source"] for e in events] == ["bridge", "depth", "mavlink"]
    c = pipe.counters()
    assert c["bridge"]["gaps"] == 1 and c["nmea"]["rejected"] == 1 and not c["errors"]


def test_samples_wait_for_the_autopilot():
    events, _ = generate(20, seed=6)
    sink = ListSink()
    pipe = Pipeline(sink=sink)
    bridge = [e for e in events if e[0] == "bridge"]
    other = [e for e in events if e[0] != "bridge"]
    for e in bridge[:41]:  # hello + 40 samples, no autopilot yet, all within HOLD_S of "now"
        pipe.feed(*e)
    early = len(sink.topic("/samples"))  # older than HOLD_S: gone out without a boat state
    held = pipe.counters()["samples"]["pending"]
    assert early + held == 40 and held >= HOLD_S * 4 - 1
    for e in other:
        pipe.feed(*e)
    pipe.flush()
    rows = sink.topic("/samples")
    assert all(r["heading"] is None for r in rows[:early])
    assert all(r["heading"] is not None for r in rows[early : early + held])
    pipe.close()


def test_without_autopilot_samples_go_out_after_the_hold():
    events, _ = generate(20, seed=7)
    sink = ListSink()
    pipe = Pipeline(sink=sink)
    for e in events:
        if e[0] == "bridge":
            pipe.feed(*e)
    rows = sink.topic("/samples")
    assert len(rows) >= 80 - HOLD_S * 4 - 2
    assert all(r["heading"] is None and r["wind_speed"] is None for r in rows)
    assert rows[0]["app_wind_speed"] is not None
    pipe.close()
    assert len(sink.topic("/samples")) == 80


def test_the_daemon_holds_samples_longer_on_an_accelerated_clock():
    """A 3-s hold in host time is 240 s of virtual time at x80: a busy machine must not drop states."""
    from forcemap.host.cli.run import _pipeline_factory

    events, _ = generate(20, seed=6)
    held = {}
    for speed in (1.0, 80.0):
        sink = ListSink()
        pipe = _pipeline_factory(None, "interpolate", speed)(sink)
        assert pipe.hold_s == HOLD_S * speed
        for e in events:
            if e[0] == "bridge":
                pipe.feed(*e)
        held[speed] = pipe.counters()["samples"]["pending"]
        pipe.close()
    assert held[1.0] <= HOLD_S * 4 + 1 and held[80.0] == 80  # 20 s of samples at 4 Hz


def test_board_reset_new_epoch_and_samples_continue():
    events, _ = generate(30, seed=8)
    sink = ListSink()
    pipe = Pipeline(sink=sink)
    k = 0
    for src, mono, wall, data in events:
        if src == "bridge":
            frames = wire.StreamDecoder().feed(data)
            fr = frames[0]
            if fr.seq > 60:  # after 15 s the board resets: new boot id, clock and counts from zero
                fr_t = fr.t_us - 15_000_000
                payload = fr.payload
                if fr.msg_type == wire.SAMPLE:
                    f = fr.fields
                    base = [
                        (c - 1000) % wire.COUNT_MOD
                        for c in [f["anemo"][0]] + [w[0] for w in f["wheels"]]
                    ]
                    chans = [(base[0], f["anemo"][1] - 15_000_000, f["anemo"][2])]
                    chans += [
                        (base[i + 1], w[1] - 15_000_000, w[2]) for i, w in enumerate(f["wheels"])
                    ]
                    payload = wire.pack_sample(f["vane_raw"], chans)
                data = wire.encode(fr.msg_type, 0xBEEF, k, fr_t, payload)
                k += 1
        pipe.feed(src, mono, wall, data)
    pipe.close()
    c = pipe.counters()
    assert c["bridge"]["resets"] == 1
    epochs = {m["epoch"] for m in sink.topic("/timesync") if m["source"] == "bridge"}
    assert len(epochs) == 2
    rows = sink.topic("/samples")
    assert len(rows) == 120
    assert all(abs(r["t"] - (T0 + 0.25 * (i + 1))) < 0.03 for i, r in enumerate(rows))


def test_approximate_sync_is_selectable():
    events, _ = generate(30, seed=9)
    rows_i, p_i = _rows(events, lambda d: [d])
    rows_a, p_a = _rows(events, lambda d: [d], sync="approximate")
    assert p_a.sync == "approximate" and len(rows_a) == len(rows_i)
    diffs = [
        abs(a["heading"] - b["heading"])
        for a, b in zip(rows_a, rows_i, strict=True)
        if a["heading"] is not None
    ]
    assert max(diffs) > 0  # nearest-neighbour states differ from interpolated ones


def test_depth_and_water_temp_topics(survey):
    d = survey[2].topic("/depth")
    assert {m["sentence"] for m in d} == {"DPT", "DBT", "MTW"}
    dpt = next(m for m in d if m["sentence"] == "DPT")
    dbt = next(m for m in d if m["sentence"] == "DBT")
    assert dpt["depth"] == pytest.approx(dbt["depth"] + 0.3, abs=0.02)  # DPT carries a 0.3 m offset


def test_against_the_simulator_truth(tmp_path):
    """The simulator's river survey through the pipeline, against its truth, within the bounds of
    docs/COMPENSATION.md: wind by the vane's 22.5 deg steps and hunting, current by the wheels."""
    import csv

    import numpy as np
    from forcemap.host.fuse.calibration import Calibration
    from forcemap.sim_devices import engine

    sink = ListSink()
    pipe = Pipeline(Calibration(depth_offset_m=0.2), sink)
    engine.Simulation(seed=2, truth_dir=tmp_path).run(
        240.0, lambda src, t, data: pipe.feed(src, t + 2_000_000, t + 2_000_000, bytes(data))
    )
    pipe.close()
    assert not pipe.errors
    truth = list(csv.DictReader(open(tmp_path / "samples.csv")))
    tt = np.array([float(r["t"]) for r in truth])

    cols = {
        k: np.array([float(r[k]) for r in truth])
        for k in ("wind_east", "wind_north", "current_east", "current_north", "depth")
    }

    def at(t, k):
        return float(np.interp(t, tt, cols[k]))

    rows = [
        r
        for r in sink.topic("/samples")
        if r["wind_east"] is not None and r["current_east"] is not None
    ]
    assert len(rows) > 900
    werr, cerr, perr, derr, excess = [], [], [], [], []
    for r in rows:
        t = r["t"]
        we = math.hypot(r["wind_east"] - at(t, "wind_east"), r["wind_north"] - at(t, "wind_north"))
        werr.append(we)
        excess.append(we - 2 * math.sin(math.radians((11.25 + 15.0) / 2)) * r["app_wind_speed"])
        cerr.append(
            math.hypot(
                r["current_east"] - at(t, "current_east"),
                r["current_north"] - at(t, "current_north"),
            )
        )
        pe = r["current_speed_paper"] * math.sin(math.radians(r["current_dir_paper"]))
        pn = r["current_speed_paper"] * math.cos(math.radians(r["current_dir_paper"]))
        perr.append(math.hypot(pe - at(t, "current_east"), pn - at(t, "current_north")))
        if r["depth"] is not None:
            derr.append(r["depth"] - at(t, "depth"))
    assert max(excess) < 0.3  # vane 11.25 deg + 3 sigma of 5 deg hunting, anemometer 0.3 m/s
    assert float(np.percentile(cerr, 95)) < 0.2 and float(np.median(cerr)) < 0.06
    assert float(np.median(perr)) > 5 * float(
        np.median(cerr)
    )  # least squares is the better default
    assert abs(float(np.mean(derr))) < 0.05 and float(np.percentile(np.abs(derr), 95)) < 0.3


def test_hello_is_metadata_and_checked_against_the_config():
    sink = ListSink()
    pipe = Pipeline(sink=sink)
    hello = wire.pack_hello((1, 2, 3), 1, 250_000, 30, 2.0, [10.8, 10.8, 12.0, 10.8], "nano", "A0")
    pipe.feed("bridge", 1, int(T0 * 1e9), wire.encode(wire.HELLO, 9, 0, 10, hello))
    meta = dict(sink.meta)["hello"]
    assert meta["fw_version"] == "1.2.3" and meta["boot_id"] == "9"
    bad = pipe.counters()["bridge"]["hello_differs_from_config"]
    assert bad == ["anemometer.mps_per_hz", "wheels[2].pulses_per_m"]


def test_a_failing_sink_does_not_stop_the_rest():
    class Flaky(ListSink):
        def write(self, topic, log_time_ns, message):
            if topic == "/bridge/status":
                raise RuntimeError("disk full")
            super().write(topic, log_time_ns, message)

    events, _ = generate(12, seed=12)
    sink = Flaky()
    pipe = Pipeline(sink=sink)
    for e in events:
        pipe.feed(*e)
    pipe.close()
    assert pipe.counters()["errors"] == {"bridge_internal": 1}
    assert len(sink.topic("/samples")) == 48
