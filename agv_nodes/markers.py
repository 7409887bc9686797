"""The marker facts of Baker (1983): patterns, templates and the detector threshold tables.

Shared by the world (cards, photodiode calibration) and the position sensor (thresholds, matching).
All in CODE space (5.3.5.2): the high nibble is image row R1, the low nibble R2, and bit 3 of a
nibble column C1, the one that sees a feature first in forward travel; detector d = 1..8 (ADC
address d-1) is row R1 column C_d for d <= 4, else row R2 column C_(d-4).
"""

# The adc_snapshot record's fields for detectors 1..8, lit (IREDs on) and dark (off).
LIT_FIELDS = tuple(f'lit_{d}' for d in range(1, 9))
DARK_FIELDS = tuple(f'dark_{d}' for d in range(1, 9))
SNAPSHOT_FIELDS = LIT_FIELDS + DARK_FIELDS


def snapshot_record(lit: list[int], dark: list[int]) -> dict[str, int]:
    """Return the adc_snapshot record of 8 lit and 8 dark conversions (SNAPSHOT_FIELDS' order).

    A dict display, not dict(zip()): the world makes one 340 times a simulated second, and
    this is half the cost (test_world checks the two alike).
    """
    l1, l2, l3, l4, l5, l6, l7, l8 = lit
    d1, d2, d3, d4, d5, d6, d7, d8 = dark
    return {'lit_1': l1, 'lit_2': l2, 'lit_3': l3, 'lit_4': l4,
            'lit_5': l5, 'lit_6': l6, 'lit_7': l7, 'lit_8': l8,
            'dark_1': d1, 'dark_2': d2, 'dark_3': d3, 'dark_4': d4,
            'dark_5': d5, 'dark_6': d6, 'dark_7': d7, 'dark_8': d8}

# Location markers (Baker 1983, 4.3, fig 4.6; templates of UCTAB): rows R1/R2, columns C1..C4.
LOCATION_PATTERNS: dict[int, tuple[str, str]] = {  # CODE 78H, 3CH, 5AH, 1EH
    0: ('BWWW', 'WBBB'), 1: ('BBWW', 'WWBB'), 2: ('BWBW', 'WBWB'), 3: ('BBBW', 'WWWB')}
# The 200 x 80 mm stop strip S1..S10 reconstructed from the EDGE table (Baker 1983, 4.3,
# fig 4.4): view k is columns S(8-k)..S(11-k); the centre view 4 is S4..S7.
STOP_STRIP: tuple[str, str] = ('BBBWBWBBBB', 'BBBBBWWBBB')
WHITE_CARD: tuple[str, str] = ('WWWW', 'WWWW')  # all-white control of the belt tests (7.1.2)
ELEMENT_WIDTH = 0.020  # m, one element (thesis 4.3)
ELEMENT_HEIGHT = 0.040  # m

EDIM = 0x0E  # identity reported for the stop-marker centre view while navigating
SLOW1 = 0x14  # 20 % duty: positioning creep speed (PC6/1 constant at 0022H)

# UCTAB (PC6/1 0031H): template -> identity, in listing order (Baker 1983, App. B.1).
LOCATION_TABLE: tuple[tuple[int, int], ...] = (
    (0x78, 0), (0x5A, 2), (0x3C, 1), (0x1E, 3), (0xA3, EDIM))
# EDGE (PC6/1 0023H): views 1-7, template and speed byte (Baker 1983, App. B.1), and the
# distance still to travel to the stop point when the view is aligned (Baker 1983, 4.3,
# fig 4.4b), mm.
STOP_VIEWS: tuple[tuple[int, int, int], ...] = (
    (0x08, SLOW1, 60), (0x8C, SLOW1, 40), (0x46, SLOW1, 20), (0xA3, 0x00, 0),
    (0x51, SLOW1, -20), (0x20, SLOW1, -40), (0x10, SLOW1, -60))
CENTRE_VIEW = 4

# Table 7.1: white (THRON) and black (THROFF) thresholds per detector, running-sum units (x4).
THRESHOLDS: dict[str, dict[str, tuple[int, ...]]] = {
    'sensor1': {'white': (290, 418, 473, 434, 308, 456, 707, 406),
                'black': (136, 199, 242, 156, 160, 262, 344, 130)},
    'sensor2': {'white': (564, 538, 326, 564, 378, 366, 144, 384),
                'black': (262, 267, 157, 237, 212, 167, 122, 180)},
}


def code_of(rows: tuple[str, str], first_column: int = 0) -> int:
    """Return the CODE byte of four columns of a card starting at `first_column` (C1 first)."""
    code = 0
    for row in rows:
        for ch in row[first_column:first_column + 4]:
            code = (code << 1) | (ch == 'W')
    return code


def stop_view_columns(view: int) -> int:
    """First strip column (0-based) of stop view 1..7: view k shows S(8-k)..S(11-k)."""
    return 7 - view


def trough_and_peak(unit: str, fraction: tuple[float, float] = (0.2, 0.8)
                    ) -> list[tuple[float, float]]:
    """Per detector (trough, peak) in x4 units, threshold = trough + p * amplitude (7.1.3).

    The thesis set WHITE at 80 % and BLACK at 20 % of the worst-case amplitude; reading the
    percentages from the trough fits Table 7.1.
    """
    lo, hi = fraction
    out = []
    for white, black in zip(THRESHOLDS[unit]['white'], THRESHOLDS[unit]['black'], strict=True):
        amplitude = (white - black) / (hi - lo)
        trough = black - lo * amplitude
        out.append((trough, trough + amplitude))
    return out
