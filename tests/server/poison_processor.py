"""A processor for live crash tests (``PDR_PROCESSOR=tests.server.poison_processor:PoisonProcessor``): counts batches
like :class:`tests.server.conftest.CountingProcessor`, but kills its whole process (``os._exit(70)``, as a segfault
in native code would) on a batch from a device whose model is ``poison``."""

from __future__ import annotations

import os

from pdr.recording import Recording
from server.processing import ProcessorOutput
from tests.server.conftest import CountingProcessor

EXIT_CODE = 70


class PoisonProcessor(CountingProcessor):
    def update(self, recording: Recording) -> ProcessorOutput:
        if recording.device.model == "poison":
            os._exit(EXIT_CODE)
        return super().update(recording)
