"""The work of the BiteMesh module, without Qt: ``logic.BiteMeshLogic`` runs in Slicer and against slicer-core."""
