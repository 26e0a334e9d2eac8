"""Recordings of 2 to 15 samples (the readers take 2 and more) were an internal error of fit texture, fit taps and
compare: scipy's zero-phase high-pass refused a signal no longer than its edge padding. Each verb now gives its own
one-line reason; longer signals are filtered exactly as before."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import sosfiltfilt

from flowtex.cli import main
from flowtex.dsp.filter_design import butterworth_sos, zero_phase_highpass
from flowtex.io.recordings import save_recording
from tests.conftest import REPO

VERBS = {
    "fit texture": (["fit", "texture", "{rec}", "--speed", "speed", "--order", "2,1", "-o", "{out}.json"], "recording too short"),
    "fit taps": (["fit", "taps", "{rec}", "--accel", "accel", "--force", "normal_force", "--speed", "speed", "-o", "{out}.json"],
                 "no tap"),
    "compare": (["compare", str(REPO / "graphs" / "data" / "synthetic_texture.json"), "{rec}", "--speed", "speed"],
                "recording too short to compare"),
}


@pytest.mark.parametrize("n", [2, 15])
@pytest.mark.parametrize("verb", list(VERBS))
def test_a_recording_of_a_few_samples_is_one_line_not_an_internal_error(tmp_path, capsys, n, verb):
    rec = tmp_path / "short.npz"
    t = np.arange(n) / 1000.0
    save_recording(rec, {"accel": np.sin(300 * t), "speed": np.full(n, 100.0), "normal_force": np.ones(n)}, rate=1000.0)
    argv, says = VERBS[verb]
    assert main([a.format(rec=rec, out=tmp_path / "out") for a in argv]) == 1
    err = [line for line in capsys.readouterr().err.splitlines() if not line.startswith("flowtex: compiling")]
    assert len(err) == 1 and says in err[0] and "internal error" not in err[0], err


def test_signals_longer_than_the_padding_are_filtered_as_before():
    x = np.random.default_rng(1).normal(size=(2, 16))
    sos = butterworth_sos("highpass", 4, [10.0], 1000.0)
    np.testing.assert_array_equal(zero_phase_highpass(x, 1000.0, 10.0), sosfiltfilt(sos, x))
    assert zero_phase_highpass(np.ones(2), 1000.0, 10.0).shape == (2,)
