"""A JACK capture client for the audio tests: records its input port until SIGTERM, then saves the frames (before it
closes its stream).

Run as ``python jack_capture.py OUT.npy RATE BLOCK`` with JACK_DEFAULT_SERVER naming the server. Prints
``ready`` once its port exists. It goes through PortAudio's JACK host API (sounddevice), like flowtex itself.
"""

from __future__ import annotations

import signal
import sys
import threading

import numpy as np
import sounddevice as sd


def main() -> None:
    out, rate, block = sys.argv[1], float(sys.argv[2]), int(sys.argv[3])
    chunks: list[np.ndarray] = []
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    jack = next(i for i, a in enumerate(sd.query_hostapis()) if "JACK" in a["name"])
    device = sd.query_hostapis(jack)["default_input_device"]

    def callback(indata, frames, time_info, status):  # noqa: ARG001
        chunks.append(indata.copy())

    with sd.InputStream(samplerate=rate, blocksize=block, device=device, channels=1, dtype="float32", callback=callback):
        print("ready", flush=True)
        done.wait()
        got = list(chunks)  # saved before the stream closes: closing a JACK client can hang on a loaded machine (a
        # client jackd found late is waited for), and the test then kills this process; what was captured is kept
        np.save(out, np.concatenate(got)[:, 0] if got else np.zeros(0, dtype=np.float32))


if __name__ == "__main__":
    main()
