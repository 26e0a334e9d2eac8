"""A kernel's fingerprint (the cache key of the generated code calling it) is that of the code the function runs."""

from __future__ import annotations

import importlib.util
import sys
import time

from flowtex.graph.jit import kernel_fingerprint

BODY = "def kernel(x):\n    return x + {}\n"


def _import(path, name):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def test_a_file_edited_after_the_import_keeps_the_fingerprint_of_the_code_that_runs(tmp_path):
    path = tmp_path / "kernels_fp.py"
    path.write_text(BODY.format(1))
    try:
        first = _import(path, "kernels_fp")
        before = kernel_fingerprint(first.kernel)
        time.sleep(0.01)
        path.write_text(BODY.format(2) + "# edited\n")  # the imported function still returns x + 1
        assert kernel_fingerprint(first.kernel) == before  # re-reading the file gave the edit's text for the old code
        again = _import(path, "kernels_fp")  # imported again: the edit's code, and its own fingerprint
        assert again.kernel(0) == 2 and kernel_fingerprint(again.kernel) != before
    finally:
        sys.modules.pop("kernels_fp", None)
