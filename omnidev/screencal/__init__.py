"""Screen-to-camera calibration (dissertation ch. 5): a fixed camera watching a display
or projection screen learns the map from image pixels to screen pixels from three
displayed patterns (white, black, an N x N dot matrix).

Modules: ``patterns`` (the patterns for any screen resolution), ``features``
(threshold distribution map, local binarization, the screen border polygon, the
dot centres), ``transform`` and ``calibration`` (image -> screen by the
dissertation's inverse-distance weighting and better interpolants beside it),
``tsai`` (the dissertation's baseline).

Coordinates: image pixels (u right, v down) and screen pixels (x right, y down),
both with the centre of the top-left pixel at (0, 0).
"""
