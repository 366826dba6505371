"""The mounting check under way: a vehicle moves along its forward axis.

The self-check's mounting check (:mod:`.self_check`) sees an IMU mounted rotated about a
horizontal axis in the coarse window (the vehicle frame far from level), not one turned
about the vertical: gravity looks the same. Under way it shows in the GNSS velocity: a car,
a ship, a USV or an aircraft moves along its forward axis, forwards or backwards, give or
take a sideslip or a crab angle of a few degrees (a current across a slow boat: 20-30 deg;
the simulated USV in severe sea at about 1 m/s, its sway and heave included: medians up to
21 deg above 1 m/s, 24 deg above 0.3 m/s). So at each GNSS epoch above :data:`MIN_SPEED`,
once the filter's heading is known (1-sigma within :data:`MAX_HEADING_SIGMA`), the
direction of the velocity in the vehicle frame is taken; when the median of its angle from
the forward axis over the last :data:`WINDOW` such epochs (at least :data:`MIN_EPOCHS`) is
beyond ``mounting_check_max_sideslip_deg`` (45 deg), the IMU is taken for turned about the
vertical with ``imu_mounting_rpy_deg`` untold: the attitude found is the IMU's, not
``base_link``'s (simulated: a ship with its IMU turned 90 deg, published 91 deg off under a
0.09 deg sigma and ``aligned``). The fine stage then publishes it as unknown and is never
``aligned`` (``FineStage.mounting_doubt``). A vehicle that moves sideways for a minute (a
holonomic robot) needs the check off (180). An IMU turned 180 deg is not seen: backwards
is taken for reversing (seed 003's car backs up for a minute at 5 m/s).

**Each epoch's angle in the heading known now.** An epoch's angle was taken with the
heading the filter had then; the filter's later corrections about the vertical
(:meth:`SideslipCheck.correct`, from every GNSS and heading update) are what it has
learnt since about that heading, so each stored angle is moved by the corrections made
after it before the median is taken. Why: a ship under way whose coarse heading came from
the GNSS track starts with the course as its heading, so its first epochs' angles are
near zero by construction; its gyros then turn the heading to the IMU's, 80 deg away,
within a minute, and a window of such stale angles kept the median under the bound for
20 more epochs. With the aided reprocessing the stage was ``aligned`` at 71 s, 10 s before
the check saw the mounting (test_installation). Not needed for a first-order question:
the corrections are what the filter now believes its heading then was off by.
"""
import math
import statistics
from collections import deque

import numpy as np

#: epochs over which the median is taken
WINDOW = 60
#: horizontal speed (m/s) below which an epoch is not judged
MIN_SPEED = 1.0
#: the latest epochs whose median the suggested mounting yaw is (the filter's heading
#: moves from the track's, where the coarse stage put it, to the IMU's)
LATEST = 10
#: epochs needed before the check judges
MIN_EPOCHS = 20
#: the heading 1-sigma (rad) within which the filter's heading is good enough to judge by
MAX_HEADING_SIGMA = math.radians(10.0)


def median(values):
    """Return the median of the floats ``values`` (NaN if one is NaN, as ``np.median``).

    ``statistics.median`` on a sorted list: the same number as ``np.median`` (the middle
    one, or the two middle ones' sum halved) for the 60 values of a window, without
    numpy's overhead at every GNSS epoch.
    """
    values = list(values)
    if any(map(math.isnan, values)):
        return math.nan
    return statistics.median(values)


class SideslipCheck:
    """Median angle of the vehicle-frame GNSS velocity from forward (module docstring).

    ``max_sideslip_deg`` the bound (180: never).
    """

    def __init__(self, max_sideslip_deg, min_speed=MIN_SPEED):
        self.limit = float(max_sideslip_deg)
        self.min_speed = float(min_speed)
        #: (angle deg as taken, the corrections' sum deg when taken)
        self.angles = deque(maxlen=WINDOW)
        #: the sum of the filter's corrections about the vertical so far, deg
        self.corrected = 0.0

    def correct(self, phi_up):
        """Take a filter update's correction about the vertical, ``phi_up`` rad.

        ``phi_up`` as :func:`~.aligned_gate.rotation_vector` gives it (``C_after = (I -
        [phi x]) C_before``): the heading moved by ``-phi_up``, so an angle from the
        forward axis taken before moves by ``+phi_up``.
        """
        self.corrected += math.degrees(phi_up)

    def _now(self):
        """Return the stored angles in the heading known now, folded to +-90 deg (deg)."""
        out = []
        for a, c in self.angles:
            a += self.corrected - c
            a = (a + 180.0) % 360.0 - 180.0
            if abs(a) > 90.0:               # reversing: the same axis (seed 003's car backs
                a -= math.copysign(180.0, a)    # up for a minute at 5 m/s)
            out.append(a)
        return out

    def add(self, v_n, C_b_n, var_yaw):
        """Take an epoch's ENU velocity ``v_n`` (3,) with the attitude ``C_b_n`` (3, 3).

        ``var_yaw``: the published heading variance (rad^2). Returns the finding ('' while
        there is none).
        """
        if self.limit >= 180.0 or var_yaw > MAX_HEADING_SIGMA ** 2:
            return ''
        v_n = np.asarray(v_n, dtype=float)
        if not math.hypot(v_n[0], v_n[1]) >= self.min_speed:
            return ''
        v_b = C_b_n.T @ v_n
        self.angles.append((math.degrees(math.atan2(v_b[1], v_b[0])), self.corrected))
        if len(self.angles) < MIN_EPOCHS:
            return ''
        a = self._now()
        off = median(map(abs, a))
        if off <= self.limit:
            return ''
        yaw = -median(a[-LATEST:])
        return (f'the GNSS velocity lies {off:.0f} deg from the '
                f'vehicle\'s forward axis (median over the last {len(a)} epochs above '
                f'{self.min_speed:g} m/s; mounting_check_max_sideslip_deg {self.limit:g}): the '
                'IMU is probably mounted turned about the vertical and imu_mounting_rpy_deg\'s '
                'yaw is untold, so the attitude found is not base_link\'s: roll, pitch and '
                'heading published as unknown, never aligned. Set imu_mounting_rpy_deg (its '
                f'yaw about {yaw:.0f} deg lately, if the vehicle moves forward), or set '
                'mounting_check_max_sideslip_deg to 180 for a vehicle that moves sideways')
