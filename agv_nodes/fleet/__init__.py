"""Several trucks on one floor: the track graph they are directed on."""
