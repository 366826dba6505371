"""The alignment node's /diagnostics messages and the exceptions its callbacks raise.

What a report says is plain arithmetic in :mod:`sins_align_ros.io.diagnostic_report`
(shared with the replay's result bag); :func:`status_message` makes it a
``diagnostic_msgs/DiagnosticStatus``. :class:`CallbackErrors` logs, counts and reports
the exceptions raised in the node's callbacks.
"""
import math
import time
import traceback

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

from ..io.diagnostic_report import LOG_PERIOD_S


def status_message(report):
    """Return the ``DiagnosticStatus`` of a report (``diagnostic_report.StatusReport``)."""
    return DiagnosticStatus(level=bytes([report.level]), name=report.name,
                            hardware_id=report.hardware_id, message=report.message,
                            values=[KeyValue(key=k, value=v) for k, v in report.values])


class CallbackErrors:
    """Exceptions raised in the node's callbacks: logged, counted, said on /diagnostics.

    Each is logged at ERROR with its traceback, at most once per :data:`LOG_PERIOD_S` for
    the same text (a repeat within that is counted only).
    """

    def __init__(self, logger):
        self.logger = logger
        #: exceptions since the node started
        self.count = 0
        self._period = []
        self._logged = {}             # text -> wall time of its last log line

    def add(self, exc):
        """Log and count ``exc``; return its one-line text."""
        text = f'{type(exc).__name__}: {exc}'
        self.count += 1
        self._period.append(text)
        now = time.monotonic()
        if now - self._logged.get(text, -math.inf) >= LOG_PERIOD_S:
            self._logged[text] = now
            trace = ''.join(traceback.format_exception(exc)).rstrip()
            self.logger.error(f'exception in a callback; the alignment restarts:\n{trace}')
        return text

    def lines(self):
        """Return the period's exceptions as ERROR conditions ``[(2, text)]`` and forget them."""
        out = [(2, f'exception in a callback ({t})') for t in self._period]
        self._period = []
        return out
