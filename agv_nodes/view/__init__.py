"""Seeing a run: the truck's odometry and frames, the floor's scene, a Foxglove live view."""
