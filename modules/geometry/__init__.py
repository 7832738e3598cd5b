"""Geometry shared by several domains (pure numpy/scipy, no runtime imports).

* ``transforms`` — 4x4 homogeneous transforms, twists and the camera-to-tool twist transform.
* ``val`` — VAL locations (X, Y, Z, O, A, T) of the Rochester Puma to and from transforms.
* ``rochester_head`` — the camera-head chain A9..A14 (CamPos from altitude and azimuth), aiming.
* ``rochester_stereo`` — the Rochester camera model and the guide's two stereo methods.
* ``rays`` — rays through pixels, triangulation of two or more rays, and epipolar lines.
* ``polygon_moments`` — exact area moments of a closed polygon, and angles between axes.
"""
