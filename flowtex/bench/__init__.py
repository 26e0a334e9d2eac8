"""Speed against error: knob sweeps over a graph (``flowtex bench``, docs/bench.md)."""
