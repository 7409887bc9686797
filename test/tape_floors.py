"""Tape floors the camera-truck tests write into tmp_path: one straight tape of a given length."""


def straight_tape(name: str, description: str, length: float, start_at: float) -> str:
    """Return a layout file's text: a straight tape `length` m long, the truck `start_at` m on."""
    return f"""\
layout: {name}
description: {description}
vehicle: concic2
kind: tape
tapes:
  - id: main
    start: [0.0, 0.0, 0.0]
    width: 0.058
    segments:
      - {{straight: {length}}}
start: {{path: main, at: {start_at}}}
"""
