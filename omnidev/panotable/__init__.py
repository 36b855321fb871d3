"""Pano-mapping tables (dissertation ch. 4): any omni-camera learned from landmarks.

Modules:

- :mod:`~omnidev.panotable.table`: the radial stretching function, its fit to
  landmarks and the table of Algorithm 2 (pure math);
- :mod:`~omnidev.panotable.camfile`: ``kind: pano-table`` calibration files and
  the pano-table camera model that builds remap maps from a table;
- :mod:`~omnidev.panotable.center`: the image center of a catadioptric image
  (sec. 4.3: the mirror disc and its cut-off circle);
- :mod:`~omnidev.panotable.landmarks`: landmark CSV files (``u,v,X,Y,Z``);
- :mod:`~omnidev.panotable.plots`: the fit plot (imports matplotlib).
"""

from omnidev.panotable.camfile import PanoTableCamera, load_table, save_table
from omnidev.panotable.center import OmniCircles, detect_omni_circles, fit_circle
from omnidev.panotable.landmarks import Landmarks, read_landmarks_csv
from omnidev.panotable.table import Calibration, PanoTable, calibrate, fit_radial, radial

__all__ = [
    "Calibration",
    "Landmarks",
    "OmniCircles",
    "PanoTable",
    "PanoTableCamera",
    "calibrate",
    "detect_omni_circles",
    "fit_circle",
    "fit_radial",
    "load_table",
    "radial",
    "read_landmarks_csv",
    "save_table",
]
