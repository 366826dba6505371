"""The alignment node's parameters: declared, checked when set, applied after.

The node declares the alignment parameters (:data:`~sins_align_ros.align.params.
ALIGNMENT_PARAMS`) and its own (ROS interface: frames, periods, batching). A change to an
alignment parameter is checked together with the others before rclpy accepts it (an
unknown ``fine_filter`` is refused with the reason) and, once set, restarts the session
with the new values; a node parameter takes effect at its next use.

An ``imu_noise_file`` (read-only: read at start-up) sets the noise parameters it gives
(:mod:`~sins_align_ros.io.imu_noise_file`) where no override names them: the declared
parameters then hold the file's values, so ``ros2 param get`` shows what the filter uses.
"""
from rcl_interfaces.msg import SetParametersResult
from rclpy.parameter import Parameter

from ..align import params as prm
from ..io import imu_noise_file
from .params import declare, overrides

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
        #: what the IMU noise file said and set (one line, '' without one); why it was
        #: refused ('' when it was not: a managed node refuses it at ``configure``)
        self.noise_summary, self.noise_error = '', ''
        try:
            self._take_noise_file(node)
        except ValueError as exc:
            if check:
                raise
            self.noise_error = str(exc)
        #: the alignment parameters as set, the session's values
        self.align = {k: v for k, v in self.p.items() if k in ALIGN_NAMES}

    def _take_noise_file(self, node):
        """Set the parameters the ``imu_noise_file`` gives and no override names; log them.

        Raises ``ValueError`` (one line) for a bad file or a value it gives outside the
        parameter's range.
        """
        given = set(overrides(node))
        values, self.noise_summary = imu_noise_file.apply(self.p, given, prm.defaults())
        if not self.noise_summary:
            return
        changed = [k for k in imu_noise_file.SETS if values[k] != self.p[k]]
        results = node.set_parameters([Parameter(k, value=float(values[k])) for k in changed])
        for k, res in zip(changed, results):
            if not res.successful:
                raise ValueError(f'{self.p["imu_noise_file"]} gives {k} = {values[k]:.6g}, '
                                 f'refused: {res.reason}')
            self.p[k] = float(values[k])
        node.get_logger().info(self.noise_summary)

    def refused(self):
        """Return the reasons the declared values are refused, '' when none is."""
        errs = [err for err in (p.check(self.p[p.name]) for p in PARAMS) if err]
        return '; '.join(errs + ([self.noise_error] if self.noise_error else []))

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
