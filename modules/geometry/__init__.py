"""Geometry shared by several domains: rays, triangulation and epipolar lines."""
