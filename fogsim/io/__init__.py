"""File I/O as one package: atomic writes and their leftovers (``atomic``, ``parts``), one file under two
names (``links``), bounded text and JSON (``documents``), images (``images``, ``pixel_bound``), EXR and depth
files (``exr``, ``depth_files``), what a file's header declares (``headers``), whether an image file is whole
(``integrity``) and paths from the command line (``paths``).

Conventions: RGB arrays are H×W×3 in RGB order (OpenCV's BGR never leaves this package); depth arrays are
H×W float32 in metres. Every writer writes a temporary file beside the target and renames it, so a killed
job never leaves a half-written output.

Importing any module of the package first sets ``OPENCV_IO_ENABLE_OPENEXR=1`` (OpenCV's EXR codec is off
without it), here, before :mod:`fogsim.io.images` or :mod:`fogsim.io.exr` imports ``cv2``.
"""
import os

os.environ.setdefault("OPENCV_IO_ENABLE_OPENEXR", "1")
