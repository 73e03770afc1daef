"""Fill the Numba caches on the second core while the test session's collection compiles on the first.

tests/conftest.py starts this script when the whole suite runs (`pytest` without paths, as CI runs it). On an empty
cache (a fresh clone) the collection's first import of the device pipeline compiles every kernel module in the
order `ropecam.device.pipeline._kernels.__init__` imports them, then the protocol's (~150 s of one core in all).
This process compiles the part that order reaches last (`DEVICE_LAST`: the blur split's modules, the plane's,
the paper method's, ...), importing those modules directly, without the package's
``__init__`` (which would start with the same modules as the collection): when the collection reaches them it
loads them from the cache instead of compiling them (measured, cold: the collection's import ~154 s -> ~78 s of
one core). Then it compiles `LATER`: the protocol's kernels and the host's, which the collection reaches only with
the host tests.

A kernel both processes reach before either has cached it is compiled twice, no worse than without this script;
Numba writes each cache file whole (a temporary file renamed), so neither process reads a half-written one. On a
filled cache both only load.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys

KERNELS = "ropecam.device.pipeline._kernels"
DEVICE_LAST = (
    "geometry",
    "offsets",
    "polylines",
    "smoothing",
    "split_shapes",
    "split_frame",
    "plane",
    "revisits",
    "paper",
    "static_shape",
    "thresholds",
    "tone",
)
"""Modules of `KERNELS` in the order compiled here: the reverse of where the package's ``__init__`` reaches them
(its last: ``frame``'s blur split and plane, then ``paper`` ... ``tone``; ``geometry`` is what the split needs that
it reaches earlier, with ``contour``). Each import compiles (or loads) the modules it imports first."""
LATER = ("ropecam.shared.protocol._kernels", "ropecam.host.sim._kernels", "ropecam.host.model._kernels")
"""Imported whole after `DEVICE_LAST`: the protocol's kernels (the collection's next after the device's), then the
host's."""


def main() -> None:
    """Compile `DEVICE_LAST` without the kernel package's ``__init__``, then `LATER`."""
    from ropecam.shared.jit import drop_stale_caches

    spec = importlib.util.find_spec(KERNELS)  # imports its parents (no kernels), not the package itself
    assert spec is not None and spec.submodule_search_locations, KERNELS
    sys.modules[KERNELS] = importlib.util.module_from_spec(spec)  # the package, its __init__ not run
    drop_stale_caches(spec.submodule_search_locations[0])  # what its __init__ does first
    for name in DEVICE_LAST:
        importlib.import_module(f"{KERNELS}.{name}")
    for module in LATER:
        importlib.import_module(module)


if __name__ == "__main__":
    main()
