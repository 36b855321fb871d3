"""Misaligned (non-single-viewpoint) hyperbolic-mirror cameras (dissertation ch. 2-3).

A hyperbolic mirror and a perspective camera whose lens is tilted and off-centre
relative to the mirror: ``model`` (mirror, lens, pose and the coordinate systems of
sec. 2.3), ``backproject`` (image point -> mirror point -> incident ray, sec. 2.4)
and ``forward`` (world point -> pixel, numerically), ``ringcal`` (the ring-pattern
calibration of sec. 2.3.2), ``interp`` (chapter 3's interpolation of the unfilled
pixels of a back-projected view).

Units: millimetres and radians; image pixels with the centre of the top-left
pixel at (0, 0).
"""
