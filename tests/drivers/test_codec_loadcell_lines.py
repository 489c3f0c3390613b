"""Load-cell line codec: the protocols.md §8.2 layout, configurable layouts, fuzzing."""

from __future__ import annotations

import os
import sys

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.codecs import loadcell_lines as lc

props = sys.modules["rotorbench_tests_codec_props"]  # codec_props.py, loaded by conftest.py
# ROTORBENCH_FUZZ_EXAMPLES=5000 for a deeper run than the default 300 per property
FUZZ = settings(max_examples=int(os.environ.get("ROTORBENCH_FUZZ_EXAMPLES", "300")), deadline=None)


def test_teststand_v2_transcript_in_si():
    data = (props.FIXTURES / "loadcell" / "teststand_v2.txt").read_bytes()
    dec = lc.LoadcellLineDecoder(lc.TESTSTAND_V2)
    (line,) = dec.feed(data) + dec.flush()
    v = line.values
    assert v["thrust_n"] == pytest.approx(0.412 * 9.80665)  # 412 g
    assert v["t_s"] == pytest.approx(2.004)  # 2004000 µs
    assert (v["throttle_us"], v["rpm"], v["voltage_v"], v["current_a"]) == \
        (1500, 21500, 16.12, 12.3)
    assert dec.stats.skipped_lines == 2  # the text line and the CSV header
    assert dec.stats.malformed == 0


def test_layout_from_rig_config_and_errors():
    layout = lc.LineLayout.from_config(
        {"separator": ";", "fields": ["t_ms_ignored", "", {"name": "thrust_n", "scale": 0.01,
                                                            "offset": -1}]})
    assert layout.fields[1] is None
    assert layout.parse("5;7;300") == {"t_ms_ignored": 5.0, "thrust_n": 2.0}
    assert layout.parse("5;7") is None and layout.parse("5;x;3") == {"t_ms_ignored": 5.0,
                                                                     "thrust_n": -0.97}
    space = lc.LineLayout.from_config({"separator": " ", "fields": ["a", "b"]})
    assert space.parse("1   2") == {"a": 1.0, "b": 2.0}
    for bad, why in [({}, "'fields'"), ({"fields": [3]}, r"fields\[0\]"),
                     ({"fields": [{"name": "a", "scale": "x"}]}, "numbers"),
                     ({"fields": [{"name": "a", "scale": 0}]}, "non-zero"),
                     ({"fields": ["a", "a"]}, "duplicate"), ({"fields": ["a"], "separator": 1},
                                                             "separator")]:
        with pytest.raises(lc.LayoutError, match=why) as e:
            lc.LineLayout.from_config(bad, source="rig.toml [load_cell.layout]")
        assert e.value.exit_code == 2


def test_damaged_lines_are_counted_not_raised():
    dec = lc.LoadcellLineDecoder(lc.HX711_RAW, max_line=16)
    out = dec.feed(b"123\n12 3 4\n" + b"9" * 40 + b"\n-5\ninf\n77")
    assert [m.values["raw"] for m in out] == [123.0, -5.0]
    assert dec.stats.malformed == 2  # wrong field count, over-long line
    assert dec.stats.skipped_lines == 1  # "inf" holds letters: text
    dec.flush()
    assert dec.stats.truncated == 1


# ---------------------------------------------------------------------------- properties

finite = st.floats(-1e9, 1e9, allow_nan=False)


@st.composite
def streams(draw):
    layout = lc.TESTSTAND_V2
    pieces = []
    glued = False
    for _ in range(draw(st.integers(1, 8))):
        values = {f.name: draw(finite) for f in layout.fields if f is not None}
        line = layout.format(values)
        raw = (line + draw(st.sampled_from(["\n", "\r\n"]))).encode()
        expected = lc.LoadcellLine(layout.parse(line))
        kind = draw(st.integers(0, 5))
        if kind == 0 and not glued:
            pieces.append(props.Piece(b"Press any key to exit\r\n"))
        if kind == 1:  # a line cut short by a reset: the rest of it is lost
            pieces.append(props.Piece(raw[: draw(st.integers(1, len(raw) - 2))]))
            glued = True
            continue
        # A line that lost its terminator glues onto the next one: both are lost, as on
        # any line protocol; the decoder must count them and carry on.
        pieces.append(props.Piece(raw, expected, intact=not glued))
        glued = False
    data, intact = props.assemble(pieces)
    return data, intact, draw(st.lists(st.integers(0, len(data)), max_size=6))


@FUZZ
@given(streams())
def test_fuzz_lines_through_damage_and_chunking(stream):
    data, intact, cuts = stream
    layout = lc.TESTSTAND_V2
    dec, _ = props.check_stream(lambda: lc.LoadcellLineDecoder(layout), data, intact, cuts)
    # Text lines are skipped on purpose, never counted as damage.
    assert dec.stats.skipped_lines == data.count(b"Press any key")


@FUZZ
@given(st.binary(max_size=400), st.lists(st.integers(0, 400), max_size=6))
def test_fuzz_noise_never_raises(noise, cuts):
    props.check_stream(lambda: lc.LoadcellLineDecoder(lc.TESTSTAND_V2, max_line=64), noise, [],
                       cuts)


@FUZZ
@given(st.dictionaries(st.sampled_from(["a", "b", "c"]), finite, min_size=1))
def test_format_parse_round_trip(values):
    layout = lc.LineLayout(tuple(lc.Field(k, 0.5, 1.0) for k in values))
    back = layout.parse(layout.format(values))
    assert back.keys() == values.keys()
    for k in values:
        assert back[k] == pytest.approx(values[k], rel=1e-8, abs=1e-6)
