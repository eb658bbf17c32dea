"""ffloc: visual relocalization from Python (docs/python.md).

The classes and functions are the C++ library's, in the extension module ffloc._ffloc.
"""
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
