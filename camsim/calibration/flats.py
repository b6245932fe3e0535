"""Flat frames: which files form the pairs of equal exposure, and which are unusable (saturated, not lit).

Files are paired by level, whatever their order on the command line: sorted by mean signal, a file starts a new
level when its signal exceeds the level's first by more than :data:`LEVEL_TOLERANCE` (relative) plus
:data:`LEVEL_TOLERANCE_DN`. A level must hold an even number of files; they are paired in the order given (two
pairs at one level are two points of the curve).
"""

from __future__ import annotations

import numpy as np

from camsim.core.errors import CamsimError

#: Two flats belong to one level when their mean signals differ by at most this fraction (and
#: :data:`LEVEL_TOLERANCE_DN`): the light's flicker and the shutter's jitter between the frames of a pair.
LEVEL_TOLERANCE = 0.03
#: See :data:`LEVEL_TOLERANCE`. Unit: DN.
LEVEL_TOLERANCE_DN = 2.0
#: A flat with more than this fraction of its pixels at the white level is saturated.
MAX_SATURATED_FRACTION = 1e-3
#: A flat whose mean signal exceeds this fraction of the ADC's range above the black level is too close to it.
MAX_MEAN_FRACTION = 0.9
#: Distinct levels needed.
MIN_LEVELS = 3


def check_flat(name: str, signal_dn: float, saturated_fraction: float, full_scale_dn: float) -> None:
    """Refuse a flat that cannot be used: saturated, too close to the white level, or not brighter than the darks.

    Parameters
    ----------
    name : str
        The file, for the message.
    signal_dn : float
        Its mean less the black level. Unit: DN.
    saturated_fraction : float
        The fraction of its values at or above the white level.
    full_scale_dn : float
        White level − black level. Unit: DN.

    Raises
    ------
    CamsimError
    """
    if saturated_fraction > MAX_SATURATED_FRACTION:
        raise CamsimError(f"flat {name} is saturated: {100 * saturated_fraction:.2g} % of its pixels are at the white "
                          f"level (at most {100 * MAX_SATURATED_FRACTION:g} %); shoot the brightest flats at about "
                          "70 % of the white level or less")
    if signal_dn > MAX_MEAN_FRACTION * full_scale_dn:
        raise CamsimError(f"flat {name} is too close to saturation: its mean signal is {signal_dn:.1f} DN, "
                          f"{100 * signal_dn / full_scale_dn:.0f} % of the {full_scale_dn:.0f} DN above the black "
                          f"level (at most {100 * MAX_MEAN_FRACTION:g} %)")
    if not signal_dn > 0:
        raise CamsimError(f"flat {name} is not brighter than the dark frames (mean signal {signal_dn:.2f} DN): is "
                          "it a dark frame, or are the darks lit?")


def group_levels(signal_dn, names) -> list:
    """Pair flat files by level.

    Parameters
    ----------
    signal_dn : array_like
        Each file's mean signal (mean − black level). Unit: DN.
    names : sequence of str
        The files, in the order given.

    Returns
    -------
    list of list of (int, int)
        Per level, ascending, its pairs as indices into ``names``.

    Raises
    ------
    CamsimError
        A level with an odd number of files, or fewer than :data:`MIN_LEVELS` levels.
    """
    signal = np.asarray(signal_dn, dtype=np.float64)
    order = np.argsort(signal, kind="stable")
    groups: list[list[int]] = []
    for i in order:
        if groups and signal[i] <= signal[groups[-1][0]] * (1 + LEVEL_TOLERANCE) + LEVEL_TOLERANCE_DN:
            groups[-1].append(int(i))
        else:
            groups.append([int(i)])
    levels = []
    for group in groups:
        group.sort()  # the order given
        if len(group) % 2:
            listed = ", ".join(f"{names[i]} ({signal[i]:.1f} DN)" for i in group)
            raise CamsimError(f"flat level of about {np.mean(signal[group]):.1f} DN has {len(group)} file"
                              f"{'s' if len(group) > 1 else ''} ({listed}): flats come in pairs of equal exposure "
                              "(two frames per level)")
        levels.append([(group[j], group[j + 1]) for j in range(0, len(group), 2)])
    if len(levels) < MIN_LEVELS:
        raise CamsimError(f"the flats give {len(levels)} level{'s' if len(levels) != 1 else ''}; the photon transfer "
                          f"curve needs at least {MIN_LEVELS} (pairs of flats at, e.g., 5 %, 15 %, 30 %, 50 % and 70 % "
                          "of the white level)")
    return levels
