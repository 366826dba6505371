"""The alignment node's parameters: declared, checked when set, applied after.

The node declares the alignment parameters (:data:`~sins_align_ros.align.params.
ALIGNMENT_PARAMS`) and its own (ROS interface: frames, periods, batching). A change to an
alignment parameter is checked together with the others before rclpy accepts it (an
unknown ``fine_filter`` is refused with the reason) and, once set, restarts the session
with the new values; a node parameter takes effect at its next use.
"""
from rcl_interfaces.msg import SetParametersResult

from ..align import params as prm
from .params import declare

NODE_PARAMS = prm.NODE_PARAMS
#: every parameter the node declares
PARAMS = prm.ALIGNMENT_PARAMS + NODE_PARAMS
ALIGN_NAMES = frozenset(p.name for p in prm.ALIGNMENT_PARAMS)
_BY_NAME = {p.name: p for p in PARAMS}


class AlignmentParams:
    """The declared values: ``p`` (every parameter, normalised), ``align`` (the session's).

    ``node``: the rclpy node to declare on; ``check`` false keeps invalid values for a
    later check (a managed node refuses them at ``configure``).
    """

    def __init__(self, node, check=True):
        self.p = declare(node, PARAMS, check=check)
        #: the alignment parameters as set, the session's values
        self.align = {k: v for k, v in self.p.items() if k in ALIGN_NAMES}

    def refused(self):
        """Return the reasons the declared values are refused, '' when none is."""
        return '; '.join(err for err in (p.check(self.p[p.name]) for p in PARAMS) if err)

    def check(self, changes):
        """Check ``changes`` (rclpy Parameters) with the other alignment values; the result."""
        new = dict(self.align)
        new.update({c.name: c.value for c in changes if c.name in ALIGN_NAMES})
        try:
            prm.validate(new)
        except ValueError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def apply(self, changes):
        """Take the accepted ``changes``; return the names of the alignment ones among them."""
        for c in changes:
            self.p[c.name] = _BY_NAME[c.name].normalise(c.value) if c.name in _BY_NAME \
                else c.value
            if c.name in ALIGN_NAMES:
                self.align[c.name] = c.value
        return [c.name for c in changes if c.name in ALIGN_NAMES]
