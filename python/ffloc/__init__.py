"""ffloc: visual relocalization from Python (docs/python.md).

The classes and functions are the C++ library's, in the extension module ffloc._ffloc.
"""
try:
    import numpy  # noqa: F401  (every array in and out is NumPy's)
except ImportError as error:  # found at import, not at the first call that returns an array
    raise ImportError(
        "ffloc needs NumPy, which this interpreter lacks; the module is built for /usr/bin/python3 "
        "with Debian's python3-numpy (docs/python.md)") from error

from ._ffloc import (
    Error,
    Frame,
    Localizer,
    Map,
    Result,
    Scene,
    build_map,
    estimate_absolute_pose,
    evaluate,
    load_dataset,
    read_image,
)

__all__ = [
    "Error",
    "Frame",
    "Localizer",
    "Map",
    "Result",
    "Scene",
    "build_map",
    "estimate_absolute_pose",
    "evaluate",
    "load_dataset",
    "read_image",
]
