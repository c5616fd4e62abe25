"""The Slicer module's folder (slicer_module/BiteMesh), put on sys.path so that the tests import BiteMeshLib as
Slicer does.  Needs no Slicer: a test module that imports only this (and BiteMeshLib.parameters) runs in the main
environment too.
"""
from __future__ import annotations

import sys
from pathlib import Path

MODULE = Path(__file__).resolve().parents[2] / "slicer_module" / "BiteMesh"
if str(MODULE) not in sys.path:
    sys.path.insert(0, str(MODULE))
