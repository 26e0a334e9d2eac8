"""Generated codecs against cantools, signal by signal (cantools is the reference)."""

from __future__ import annotations

from pathlib import Path

import cantools
import numpy as np
import pytest

from flowtex.errors import DataError
from flowtex.io.codec import MessageCodec, build_codecs
from flowtex.io.dbc import load_dbc

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "graphs" / "devices" / "example.dbc"

AWKWARD = """VERSION ""

NS_ :
    SIG_VALTYPE_
    VAL_

BS_:

BU_: A B

BO_ 100 Mixed: 8 A
 SG_ LeOdd : 3|11@1- (0.25,-3.5) [0|0] "" B
 SG_ BeOdd : 21|13@0+ (0.1,100) [0|0] "" B
 SG_ OneBit : 24|1@1+ (1,0) [0|1] "" B
 SG_ BeSigned7 : 38|7@0- (2,1) [0|0] "" B
 SG_ LeTail : 52|12@1+ (0.5,0) [0|2000] "" B

BO_ 2147483905 ExtBig: 8 A
 SG_ Wide : 7|64@0- (1,0) [0|0] "" B

BO_ 101 Floats: 8 A
 SG_ F32 : 0|32@1- (1,0) [0|0] "" B
 SG_ F32Be : 39|32@0- (0.5,2) [0|0] "" B

BO_ 102 Double: 8 A
 SG_ D64 : 0|64@1- (1,0) [0|0] "" B

BO_ 103 Short: 3 A
 SG_ S1 : 0|5@1+ (3,0) [0|0] "" B
 SG_ S2 : 5|19@1- (0.001,10) [-200|200] "" B

BO_ 104 Choice: 1 A
 SG_ Gear : 0|3@1+ (1,0) [0|7] "" B

VAL_ 104 Gear 0 "park" 1 "reverse" 2 "neutral" ;
SIG_VALTYPE_ 101 F32 : 1;
SIG_VALTYPE_ 101 F32Be : 1;
SIG_VALTYPE_ 102 D64 : 2;
"""


def _dbs(tmp_path):
    awk = tmp_path / "awkward.dbc"
    awk.write_text(AWKWARD)
    return [load_dbc(EXAMPLE), load_dbc(awk)]


def _random_physical(rng, sig):
    """A physical value that cantools encodes exactly (on the raw grid, within range)."""
    if sig.is_float:
        if sig.minimum is not None:
            phys = rng.uniform(sig.minimum, sig.maximum)
            raw = (phys - sig.offset) / sig.scale
        else:
            raw = rng.normal() * 1e3
        raw = float(np.float32(raw)) if sig.length == 32 else raw
        return raw * sig.scale + sig.offset
    lo = -(1 << (sig.length - 1)) if sig.is_signed else 0
    hi = (1 << (sig.length - 1)) - 1 if sig.is_signed else (1 << sig.length) - 1
    if sig.minimum is not None:
        lo = max(lo, int(np.ceil((sig.minimum - sig.offset) / sig.scale)))
        hi = min(hi, int(np.floor((sig.maximum - sig.offset) / sig.scale)))
    raw = int(rng.integers(lo, hi, endpoint=True)) if sig.length < 63 else int(rng.integers(-(1 << 62), 1 << 62))
    return raw * sig.scale + sig.offset


def test_every_signal_matches_cantools(tmp_path):
    rng = np.random.default_rng(7)
    checked = 0
    for db in _dbs(tmp_path):
        codecs = build_codecs(db)
        for msg in db.messages:
            c = codecs[msg.name]
            for _ in range(300):
                values = {s.name: _random_physical(rng, s) for s in msg.signals}
                ref = msg.encode(values, scaling=True, strict=True)
                assert c.encode(values) == ref, (msg.name, values)
                data = bytes(rng.integers(0, 256, msg.length, dtype=np.uint8))
                dec = msg.decode(data, decode_choices=False, scaling=True)
                got = c.decode(data)
                for s, v in zip(msg.signals, got, strict=True):
                    r = float(dec[s.name])
                    assert (v == r) or (np.isnan(v) and np.isnan(r)), (msg.name, s.name, data.hex())
                checked += len(msg.signals)
    assert checked > 5000


def test_clamp_to_dbc_range_then_saturate(tmp_path):
    db = _dbs(tmp_path)[0]
    msg = db.get_message_by_name("VoiceCoilCmd")
    c = MessageCodec(msg)
    # 7 A is beyond the DBC range [-2, 2]: encoded as the clamped value
    assert c.encode({"Current": 7.0, "Enable": 1, "Mode": 1}) == msg.encode({"Current": 2.0, "Enable": 1, "Mode": 1})
    assert c.encode({"Current": -7.0, "Enable": 0, "Mode": 9}) == msg.encode({"Current": -2.0, "Enable": 0, "Mode": 7})
    awk = db = _dbs(tmp_path)[1]
    m = awk.get_message_by_name("Mixed")
    c = MessageCodec(m)
    # LeOdd has no DBC range: raw saturates at 11-bit signed limits instead of wrapping
    hi = 1023 * 0.25 - 3.5
    values = {s.name: 0.0 for s in m.signals}
    values.update(BeOdd=100.0, BeSigned7=1.0)
    assert c.encode({**values, "LeOdd": 1e6}) == m.encode({**values, "LeOdd": hi})
    assert c.decode(c.encode({**values, "LeOdd": -1e6}))[0] == -1024 * 0.25 - 3.5


def test_decoder_writes_scaled_values_into_targets():
    db = load_dbc(EXAMPLE)
    msg = db.get_message_by_name("ToolPosition")
    c = MessageCodec(msg)
    view = np.zeros(3)
    dec = c.decoder([(view, 0, 1e-3, 0.0), (view, 1, 1e-3, 0.0), (view, 2, 1e-3, 5.0), None])
    data = msg.encode({"PosX": 12.345, "PosY": -400.0, "PosZ": 0.001, "PosCounter": 3})
    assert dec(data) is True
    assert view[0] == 12.345 * 1e-3 and view[1] == -0.4 and view[2] == pytest.approx(5.000001, abs=1e-15)
    assert dec(data[:5]) is False


def test_encoder_reads_sources_into_buffer():
    db = load_dbc(EXAMPLE)
    msg = db.get_message_by_name("ForceCmd")
    src = np.array([1.0, -2.5, 30.0])
    enc = MessageCodec(msg).encoder([(src, 0, 1.0, 0.0), (src, 1, 2.0, 0.0), (src, 2, 1.0, 0.0)])
    buf = bytearray(msg.length)
    enc(buf)
    assert bytes(buf) == msg.encode({"Fx": 1.0, "Fy": -5.0, "Fz": 10.0})


def test_multiplexed_message_refused():
    db = cantools.database.load_string("""VERSION ""
BO_ 300 Mux: 8 A
 SG_ Sel M : 0|8@1+ (1,0) [0|0] "" B
 SG_ V0 m0 : 8|8@1+ (1,0) [0|0] "" B
 SG_ V1 m1 : 8|8@1+ (1,0) [0|0] "" B
""", database_format="dbc")
    with pytest.raises(DataError, match="multiplexed"):
        MessageCodec(db.messages[0])


def test_malformed_dbc_one_line(tmp_path):
    bad = tmp_path / "bad.dbc"
    bad.write_text('VERSION ""\nBO_ 256 M: 8 X\n SG_ A : 0|70@1+ (1,0) [0|0] "" X\n')
    with pytest.raises(DataError) as e:
        load_dbc(bad)
    assert str(bad) in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(DataError, match="not found"):
        load_dbc(tmp_path / "missing.dbc")
    garbage = tmp_path / "garbage.dbc"
    garbage.write_text("this is not { a dbc\n")
    with pytest.raises(DataError) as e:
        load_dbc(garbage)
    assert "\n" not in str(e.value)


def test_table_codec_names_still_import_from_codec_and_codec_loads_no_numba():
    """The table codecs moved to flowtex.io.codec_tables: the old import path gives the same objects, and
    importing flowtex.io.codec alone (the generated Python codecs) does not pull in numba."""
    import subprocess
    import sys

    import flowtex.io.codec as codec
    import flowtex.io.codec_tables as tables

    for name in ("fast_ok", "pack_int64", "TableDecoder", "TableEncoder", "decode_packed"):
        assert getattr(codec, name) is getattr(tables, name)
    with pytest.raises(AttributeError, match="no attribute 'TableCodec'"):
        codec.TableCodec  # noqa: B018 - the attribute access is the test
    probe = "import sys, flowtex.io.codec; print('numba' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60, cwd=REPO, check=True)
    assert out.stdout.strip() == "False"
