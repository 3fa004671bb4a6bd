"""The processors the service runs per device role: the phone PDR pipeline, foot-mounted navigation.

Each adapter turns the library's online objects (:mod:`pdr.phone.pipeline`, :mod:`pdr.foot`) into the
:class:`server.processing.Processor` protocol: ``update(recording) -> ProcessorOutput`` and a byte state.
"""

from __future__ import annotations

from pdr.errors import InputError
from server.processing import Processor, SessionContext


def make_processor(ctx: SessionContext, state: bytes | None) -> Processor:
    """A processor for the session's device role, restored from ``state`` when given."""
    if ctx.role == "phone":
        from server.phone_processor import PhoneProcessor
        return PhoneProcessor(ctx, state)
    if ctx.role in ("left_foot", "right_foot"):
        from server.foot_processor import FootProcessor
        return FootProcessor(ctx, state)
    raise InputError(f"no processing for device role '{ctx.role}'")
