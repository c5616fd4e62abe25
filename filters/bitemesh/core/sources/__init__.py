"""What hands f to the spine: scattered points, labelled contours (the heart); voxels are bitemesh.labelmap."""
