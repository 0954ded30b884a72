"""McapLog and read_messages: JSON channels, rotation, flushing, and truncated files.

Rotation and flushing by time run on a virtual clock handed to McapLog, so how fast the machine
runs the test cannot change the number of files or what is flushed.
"""

from __future__ import annotations

import json
import math
import struct

import pytest
from forcemap.host.log.mcap import FileScan, McapLog, has_footer, iter_metadata, read_messages
from mcap.reader import make_reader


def _summary(path):
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        metadata = [m.name for m in reader.iter_metadata()]
    return summary, metadata


def test_round_trip_schemas_and_summary(tmp_path):
    with McapLog(tmp_path) as log:
        log.metadata("config", {"path": "boat.toml", "n": 3})
        for i in range(100):
            log.write("/depth", 1_000_000_000 + i, {"depth": i / 10, "bad": math.nan})
        log.write("/fix", 2_000_000_000, {"latitude": 47.1, "longitude": 8.5, "raw": b"\x01\xff"})
    summary, metadata = _summary(log.path)
    assert summary is not None and summary.statistics.message_count == 101
    assert metadata == ["config"]
    schemas = {s.name: s for s in summary.schemas.values()}
    assert "foxglove.LocationFix" in schemas
    assert all(s.encoding == "jsonschema" for s in schemas.values())
    assert {c.message_encoding for c in summary.channels.values()} == {"json"}
    msgs = list(read_messages(log.path))
    assert msgs[0].topic == "/depth" and msgs[0].message == {"depth": 0.0, "bad": None}
    topic, t, fix = msgs[-1]
    assert (topic, t) == ("/fix", 2_000_000_000) and fix["raw"] == "01ff"
    assert [m.message["depth"] for m in read_messages(log.path, "/depth")][-1] == 9.9


def test_rotation_by_size_repeats_metadata_and_finishes_every_file(tmp_path):
    log = McapLog(tmp_path, rotate_bytes=20_000, flush_interval_s=0.0)
    log.metadata("calibration", {"anemo": "0.6667"})
    for i in range(3000):
        log.write("/bridge/frame", i, {"seq": i, "pad": "x" * 40})
    log.close()
    assert len(log.paths) >= 3
    total = 0
    for path in log.paths:
        summary, metadata = _summary(path)
        assert metadata == ["calibration"]
        total += summary.statistics.message_count
    assert total == 3000
    seqs = [m.message["seq"] for m in read_messages(log.paths)]
    assert seqs == list(range(3000))


class VirtualClock:
    """A monotonic clock that moves only when the test says so."""

    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def test_rotation_by_time(tmp_path):
    clock = VirtualClock()
    log = McapLog(tmp_path, rotate_seconds=0.05, flush_interval_s=0.0, clock=clock)
    log.write("/a", 1, {})
    clock.now += 0.049
    log.write("/a", 2, {})  # not yet at the limit
    assert len(log.paths) == 1
    clock.now += 0.002
    log.write("/a", 3, {})  # past the limit: this file is finished and a new one started
    log.write("/a", 4, {})
    log.close()
    assert len(log.paths) == 2
    assert all(has_footer(p) for p in log.paths)
    assert [[m.log_time_ns for m in read_messages(p)] for p in log.paths] == [[1, 2, 3], [4]]


def test_flushed_data_is_readable_while_the_file_is_open(tmp_path):
    clock = VirtualClock()
    log = McapLog(tmp_path, flush_interval_s=0.05, clock=clock)
    log.write("/a", 1, {"i": 1})
    assert list(read_messages(log.path)) == []  # buffered: the flush interval has not passed
    clock.now += 0.051
    log.tick()  # nothing new written, but the timer flushes what is buffered
    scan = FileScan(log.path)
    assert [m.message for m in read_messages(log.path, scan=scan)] == [{"i": 1}]
    assert scan.truncated and not scan.complete  # no summary yet: read via the non-seeking path
    log.close()
    assert has_footer(log.path)


def test_file_has_a_header_before_anything_is_written(tmp_path):
    log = McapLog(tmp_path)
    assert list(read_messages(log.path)) == []  # readable, not an error
    log.close()


@pytest.mark.parametrize("compress", [True, False])
def test_truncated_anywhere_is_readable_and_loses_only_the_tail(tmp_path, compress):
    from mcap.writer import CompressionType

    log = McapLog(
        tmp_path,
        chunk_size=4096,
        compression=CompressionType.ZSTD if compress else CompressionType.NONE,
    )
    for i in range(2000):
        log.write("/nmea/sentence", i, {"i": i, "line": f"$SDDPT,{i},0.3*00"})
    log.close()
    data = log.path.read_bytes()
    cut_path = tmp_path / "cut.mcap"
    previous = -1
    for cut in list(range(0, len(data), max(1, len(data) // 97))) + [len(data) - 1, len(data)]:
        cut_path.write_bytes(data[:cut])
        got = [m.message["i"] for m in read_messages(cut_path)]
        assert got == list(range(len(got)))  # a prefix, in order, nothing invented
        assert len(got) >= previous  # more file never means fewer messages
        previous = len(got)
    assert previous == 2000


def test_write_after_close_raises_and_close_twice_is_fine(tmp_path):
    log = McapLog(tmp_path)
    log.close()
    log.close()
    with pytest.raises(ValueError):
        log.write("/a", 1, {})


def test_messages_are_compact_json(tmp_path):
    with McapLog(tmp_path) as log:
        log.write("/a", 1, {"x": (1, 2), "s": {3}})
    with open(log.path, "rb") as f:
        [(_, _, msg)] = list(make_reader(f).iter_messages())
    assert json.loads(msg.data) == {"x": [1, 2], "s": [3]}


def test_metadata_of_a_whole_file_comes_from_its_index_and_of_a_cut_one_from_its_records(tmp_path):
    """iter_metadata: the same records in file order, whole (read by the summary's index) or cut before
    its summary (read through); a record written after a message is not lost either way."""
    log = McapLog(tmp_path, chunk_size=512)
    log.metadata("calibration", {"navigation": "smoothed"})
    for i in range(200):
        log.write("/a", i, {"i": i})
    log.metadata("qa.finding.1", {"check": "latency", "value": 0.25})
    log.close()
    whole = list(iter_metadata(log.path))
    assert whole == [
        ("calibration", {"navigation": "smoothed"}),
        ("qa.finding.1", {"check": "latency", "value": "0.25"}),
    ]
    summary, _ = _summary(log.path)
    assert summary.statistics.metadata_count == 2 == len(summary.metadata_indexes)
    data = log.path.read_bytes()
    # the footer ends in summary_start, summary_offset_start (u64 each) and a CRC (u32), then the magic
    summary_start = struct.unpack_from("<Q", data, len(data) - 8 - 4 - 8 - 8)[0]
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:summary_start])
    assert not has_footer(cut)
    assert list(iter_metadata(cut)) == whole
