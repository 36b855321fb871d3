"""Pano-mapping tables (dissertation ch. 4): any omni-camera learned from landmarks.

Modules:

- :mod:`~omnidev.panotable.table`: the radial stretching function, its fit to
  landmarks and the table of Algorithm 2 (pure math);
- :mod:`~omnidev.panotable.general`: the generalized mapping (center, aspect,
  tilt, keystone, azimuth harmonics) and its fit, the order chosen by held-out
  residual;
- :mod:`~omnidev.panotable.boards`: landmarks from ChArUco boards at measured places;
- :mod:`~omnidev.panotable.evaluate`: both tables against rendered truth;
- :mod:`~omnidev.panotable.camfile`: ``kind: pano-table`` calibration files and
  the pano-table camera model that builds remap maps from a table;
- :mod:`~omnidev.panotable.center`: the image center of a catadioptric image
  (sec. 4.3: the mirror disc and its cut-off circle) or a fisheye's image
  circle, with its uncertainty;
- :mod:`~omnidev.panotable.landmarks`: landmark CSV files (``u,v,X,Y,Z``);
- :mod:`~omnidev.panotable.plots`: the fit plot (imports matplotlib).
"""

from omnidev.panotable.camfile import PanoTableCamera, load_table, save_table
from omnidev.panotable.center import (
    CenterEstimate,
    OmniCircles,
    detect_image_center,
    detect_omni_circles,
    fit_circle,
)
from omnidev.panotable.general import GeneralFit, PanoMapping, Terms, fit_general
from omnidev.panotable.landmarks import Landmarks, read_landmarks_csv
from omnidev.panotable.table import (
    Calibration,
    GeneralCalibration,
    PanoTable,
    calibrate,
    calibrate_general,
    fit_radial,
    radial,
)

__all__ = [
    "Calibration",
    "CenterEstimate",
    "GeneralCalibration",
    "GeneralFit",
    "Landmarks",
    "OmniCircles",
    "PanoMapping",
    "PanoTable",
    "PanoTableCamera",
    "Terms",
    "calibrate",
    "calibrate_general",
    "detect_image_center",
    "detect_omni_circles",
    "fit_circle",
    "fit_general",
    "fit_radial",
    "load_table",
    "radial",
    "read_landmarks_csv",
    "save_table",
]
