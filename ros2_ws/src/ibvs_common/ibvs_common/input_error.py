"""
The error every message reader raises: :class:`InputError`, with a short reason.

The reason is the key of the rejection counter on /diagnostics
(:mod:`.diagnostics`); a reader raises it rather than return NaN.
"""


class InputError(ValueError):
    """A message cannot be used; ``reason`` is a short key for the rejection counter."""

    def __init__(self, reason: str, detail: str = '') -> None:
        """Keep the short ``reason`` and a longer ``detail`` for the log."""
        super().__init__(f'{reason}: {detail}' if detail else reason)
        self.reason = reason
        self.detail = detail
