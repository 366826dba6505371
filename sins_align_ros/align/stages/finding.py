"""A monitor's one standing finding, said once (a WARN) until it changes."""


class OnceFinding:
    """Mixin: :meth:`take_findings` returns :attr:`finding` once per new text.

    The monitor sets ``finding`` (a sentence, '' while it has none).
    """

    finding = ''
    _reported = ''

    def take_findings(self):
        """Return the finding not reported yet (a WARN; and forget it)."""
        if self.finding and self.finding != self._reported:
            self._reported = self.finding
            return [self.finding]
        return []
