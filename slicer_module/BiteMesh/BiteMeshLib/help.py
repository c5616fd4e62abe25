"""The module's help text (Slicer's Help & Acknowledgement panel), kept out of BiteMesh.py."""

HELP_TEXT = """
Tetrahedral meshes for finite elements from scattered points, after Schaerer et al. ("biting" node placement):
an implicit surface (MPU, or an RBF for sparse contours), nodes about R apart, Delaunay tetrahedra, spurious
cells removed, a valid domain.<br>
<b>Input</b>: a markups point list (points on the surface), one or more markups closed curves (contours), a
surface model (its points and normals) or a segmentation (one segment).<br>
<b>Labelled contours</b>: <i>Load labelled points...</i> reads a biv-me GPFile, a CSV table or a VTP with a Label
array (LPS coordinates, as Slicer's files) into a model; or name closed curves after their surfaces (EPI, LV_ENDO_1,
...) and give a <b>Domain</b> such as EPI - LV_ENDO - RV_ENDO. One surface per label, combined by the domain and
closed by the base plane.<br>
<b>Output</b>: a model node holding the tetrahedra (an unstructured grid) coloured by radius ratio
(1 = regular tetrahedron), one model per tagged boundary surface, and the radius-ratio histogram as a table and a
plot.<br>
<b>Fibres</b>: for labelled heart contours (a biv-me GPFile; both ventricles or the LV), <i>Add fibres</i> adds the
rule-based myocardial fibres (Bayer et al. 2012) as cell arrays Fibre, Sheet, SheetNormal and HelixAngle, and
colours the mesh by helix angle; <i>Add coordinates</i> adds the ventricular coordinates (ApicoBasal, Transmural,
Rotational, Transventricular) as point arrays and the AHA 17 segments and the ventricles as cell arrays.<br>
<b>Elastic template</b>: <i>Fit template</i> moves a BiteMesh output (the template, with its surface models) onto
the input's points with the same cells, into the output model.<br>
<b>Radius R</b> sets the element size; leave it automatic to aim for <b>Cells</b> cells. The mesh is in RAS
(world) coordinates, where the input is.
"""
