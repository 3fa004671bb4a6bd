"""``pdr bench processor`` replays a session batch by batch through stored states, as a live worker does."""

import json

from server.bench.processor import STAGES


def test_command_measures_every_stage_of_the_live_batches_after_the_warm_up(capsys):
    from pdr.cli import main

    # 0.5 min -> one 47 s block of the simulated walk (walk, turn, stand); 30 s of it are warm-up.
    assert main(["bench", "processor", "--minutes", "0.5", "--warmup-s", "30", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert 12 <= result["batches_measured"] <= 20
    assert set(result["ms_per_batch"]) == set(STAGES)
    assert all(v > 0 for v in result["ms_per_batch"].values())
    assert result["state_bytes"] > 0 and result["payload_bytes"] > 0


def test_native_thread_limit_is_read_from_the_environment_and_validated():
    import pytest
    from threadpoolctl import threadpool_info

    from server.config import limit_native_threads

    assert limit_native_threads({"PDR_NATIVE_THREADS": "1"}) == 1
    assert all(pool["num_threads"] == 1 for pool in threadpool_info())
    for bad in ("0", "many"):
        with pytest.raises(ValueError, match="PDR_NATIVE_THREADS must be a positive integer"):
            limit_native_threads({"PDR_NATIVE_THREADS": bad})


def test_windows_report_the_cost_and_state_size_at_given_minutes(capsys):
    from pdr.cli import main

    assert main(["bench", "processor", "--minutes", "1.5", "--warmup-s", "30", "--at", "0,0.5", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    first, second = result["windows"]
    assert (first["minute"], second["minute"]) == (0.0, 0.5)
    assert first["batches"] == second["batches"] == 60
    assert set(first["ms_per_batch"]) == set(STAGES) and first["total_ms_per_batch"] > 0
    assert second["state_bytes"] > 0


def test_a_window_beyond_the_session_is_refused():
    import pytest

    from pdr.cli import main

    with pytest.raises(SystemExit, match="beyond the session"):
        main(["bench", "processor", "--minutes", "0.5", "--warmup-s", "10", "--at", "5"])
