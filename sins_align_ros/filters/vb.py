"""Former home of seed 004's variational-Bayes cubature filters (VBCKF, VBCH).

They now live one per module: :class:`~sins_align_ros.filters.vbckf.VBCKF`,
:class:`~sins_align_ros.filters.vbch.VBCH`; the variational-Bayes measurement update
they share (and its H-infinity posterior) is in :mod:`~sins_align_ros.filters.variational`.
"""
from .vbch import VBCH  # transition: align/ still imports this from here  # noqa: F401
from .vbckf import VBCKF  # transition: align/ still imports this from here  # noqa: F401
