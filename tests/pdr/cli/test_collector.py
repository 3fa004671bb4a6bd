"""pdr.cli.collector: the cyclic collector is paused inside the block only, whatever its state before."""

import gc

import pytest

from pdr.cli.collector import collection_paused


@pytest.mark.parametrize("enabled", [True, False])
def test_collection_paused_restores_the_former_state(enabled: bool) -> None:
    was = gc.isenabled()
    try:
        (gc.enable if enabled else gc.disable)()
        with collection_paused():
            assert not gc.isenabled()
        assert gc.isenabled() == enabled
        with pytest.raises(RuntimeError), collection_paused():
            raise RuntimeError("a failing command")
        assert gc.isenabled() == enabled
    finally:
        (gc.enable if was else gc.disable)()
