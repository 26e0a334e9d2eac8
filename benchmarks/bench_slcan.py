"""slcan receive throughput over a real pty: python-can's stock ``slcan`` vs ``FastSlcanBus``.

A child process plays the adapter (``FastSlcanBus`` in the device role on the pty master)
and, once the host has opened the channel, writes N frames as fast as the pty accepts
them (in batches of 10); the parent receives them with each host-side bus in turn and
reports frames/s (first to last frame) and the ratio. The stock interface needs pyserial
(``pip install pyserial``); without it only the fast bus is measured.

    python benchmarks/bench_slcan.py [frames=20000]
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import time

import can

from flowtex.io.slcan_fast import FastSlcanBus
from flowtex.io.slcan_pty import open_pty


def frame(i: int) -> can.Message:
    return can.Message(arbitration_id=0x100 + (i % 0x600), data=i.to_bytes(4, "little") + b"\x5a\x5a\x5a\x5a", is_extended_id=False)


def device(master_fd: int, n: int) -> None:
    dev = FastSlcanBus(master_fd, role="device")
    while not dev.is_open:
        dev.recv(0.05)
    time.sleep(0.2)  # let the host finish its set-up and start reading
    batch = []
    for i in range(n):
        batch.append(frame(i))
        if len(batch) == 10:
            dev.send_many(batch, timeout=30.0)
            batch = []
    dev.send_many(batch, timeout=30.0)
    time.sleep(0.5)
    dev.shutdown()


def measure(make_bus, n: int) -> float:
    pty = open_pty()
    ctx = mp.get_context("fork")
    proc = ctx.Process(target=device, args=(pty.master_fd, n))
    proc.start()
    bus = make_bus(pty.slave_path)
    try:
        first = bus.recv(10.0)
        if first is None:
            raise RuntimeError("no frame received")
        t0 = time.perf_counter()
        count, expect_next = 1, 1
        ok = int.from_bytes(bytes(first.data[:4]), "little") == 0
        deadline = time.monotonic() + 120.0
        while count < n and time.monotonic() < deadline:
            m = bus.recv(2.0)
            if m is None:
                break
            ok = ok and int.from_bytes(bytes(m.data[:4]), "little") == expect_next
            expect_next += 1
            count += 1
        dt = time.perf_counter() - t0
    finally:
        bus.shutdown()
        proc.join(30)
        pty.close()
    if count < n or not ok:
        print(f"  WARNING: received {count}/{n} frames, in order: {ok}")
    return (count - 1) / dt if dt > 0 else float("nan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("frames", nargs="?", type=int, default=20_000)
    a = ap.parse_args()
    fast = measure(lambda path: FastSlcanBus(path), a.frames)
    print(f"FastSlcanBus         {fast:>12,.0f} frames/s")
    try:
        import serial  # noqa: F401
    except ImportError:
        print("python-can slcan      skipped (pyserial not installed)")
        return
    stock = measure(lambda path: can.Bus(interface="slcan", channel=path, sleep_after_open=0), a.frames)
    print(f"python-can slcan     {stock:>12,.0f} frames/s")
    print(f"ratio fast/stock     {fast / stock:>12.1f}x   (pid {os.getpid()}, same pty set-up, same frames)")


if __name__ == "__main__":
    main()
