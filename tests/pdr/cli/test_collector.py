"""pdr.cli.collector: the cyclic collector is paused inside the block only, whatever its state before."""

import gc
import subprocess
import sys

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


def test_freeze_at_exit_freezes_before_the_interpreter_finalises() -> None:
    # A handler registered before runs after (atexit is last in, first out): it sees the frozen objects.
    code = ("import atexit, gc, sys; atexit.register(lambda: print(gc.get_freeze_count() > 0, flush=True)); "
            "from pdr.cli.collector import freeze_at_exit; freeze_at_exit(); freeze_at_exit(); "
            "print(gc.get_freeze_count(), flush=True)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120)
    assert out.stdout.split() == ["0", "True"]



def test_main_freezes_the_loaded_objects_while_the_command_runs_only(monkeypatch) -> None:
    import argparse

    import pdr.cli as cli

    seen: list[int] = []

    def parser(words):
        p = argparse.ArgumentParser()
        p.add_argument("-v", "--verbose", action="store_true")
        p.set_defaults(func=lambda args: seen.append(gc.get_freeze_count()))
        return p

    monkeypatch.setattr(cli, "build_parser", parser)
    gc.unfreeze()
    assert cli.main([]) == 0
    assert seen[0] > 0 and gc.get_freeze_count() == 0       # frozen while it ran, back in the collections after
