"""Whole arrays of increments and GNSS epochs through an alignment session, in time order.

The benchmarks and the tests feed simulated or recorded data this way: the IMU as the
increments it comes in (:meth:`~sins_align_ros.align.session.AlignmentSession.increments`,
no round trip through rates), the GNSS epochs and external headings through the session's
own entries and input checks, each before the IMU block that passes its stamp, as a live
node would receive them.
"""
import numpy as np

from ..align import AlignmentSession, Output
from ..units import DEG

#: sensor_msgs/NavSatStatus STATUS_FIX: the status an epoch with ``fix`` set is given
STATUS_FIX = 0


def feed_arrays(session, imu, gnss, use_velocity=True, block=100, callback=None, heading=None):
    """Feed whole increments and GNSS epochs to ``session`` in time order; return the rows.

    ``session``: an :class:`~sins_align_ros.align.session.AlignmentSession` whose clock the
    caller started (``session.start_clock``), or an
    :class:`~sins_align_ros.align.pipeline.AlignmentPipeline` the caller built and started
    (the tests that inspect its parts): it is driven through a session made around it
    (``AlignmentSession(pipeline=...)``). ``imu`` has ``t``, ``dtheta``, ``dv`` (N, ...);
    ``gnss`` has ``t``, ``lat``, ``lon`` (rad), ``h``, ``v_n`` (M, 3) (None: a
    position-only receiver), ``fix`` (M,) bool and ``pos_cov``/``vel_cov`` (ENU
    variances), or is None. ``block``: IMU samples per call. ``callback(pipeline)``, if
    given, is called with the session's pipeline after each block (e.g. to record filter
    internals). ``heading``: an external heading's ``t``, ``yaw`` (rad, the source's),
    ``var`` (M,) (``sim.gnss.heading_measurements``), given the same way, or None.
    Ends with :meth:`~sins_align_ros.align.session.AlignmentSession.finish` and returns
    the :class:`~sins_align_ros.align.output.Output` of every row.
    """
    if not isinstance(session, AlignmentSession):
        session = AlignmentSession(pipeline=session)
    outs, gi, hi = [], 0, 0
    n_h = 0 if heading is None else len(heading.t)
    n = len(imu.t)
    m = 0 if gnss is None else len(gnss.t)
    for i in range(0, n, block):
        j = min(n, i + block)
        while gi < m and gnss.t[gi] <= imu.t[j - 1] + 1e-9:
            if gnss.fix[gi]:
                session.fix(gnss.t[gi], STATUS_FIX, gnss.lat[gi] / DEG, gnss.lon[gi] / DEG,
                            gnss.h[gi], pos_var=np.asarray(gnss.pos_cov)[:2])
                if use_velocity and gnss.v_n is not None:
                    session.velocity(gnss.t[gi], gnss.v_n[gi],
                                     vel_var=np.asarray(gnss.vel_cov)[:2])
            gi += 1
        while hi < n_h and heading.t[hi] <= imu.t[j - 1] + 1e-9:
            session.heading(heading.t[hi], heading.yaw[hi], heading.var[hi])
            hi += 1
        outs.append(session.increments(imu.t[i:j], imu.dtheta[i:j], imu.dv[i:j]))
        if callback is not None:
            callback(session.pipeline)
    outs.append(session.finish())
    return Output.concat(outs)
