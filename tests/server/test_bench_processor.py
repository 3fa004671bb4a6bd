"""``pdr bench processor`` replays a session batch by batch through stored states, as a live worker does."""

import json

from server.bench_processor import STAGES


def test_command_measures_every_stage_of_the_live_batches_after_the_warm_up(capsys):
    from pdr.cli import main

    # 0.5 min -> one 47 s block of the simulated walk (walk, turn, stand); 30 s of it are warm-up.
    assert main(["bench", "processor", "--minutes", "0.5", "--warmup-s", "30", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert 12 <= result["batches_measured"] <= 20
    assert set(result["ms_per_batch"]) == set(STAGES)
    assert all(v > 0 for v in result["ms_per_batch"].values())
    assert result["state_bytes"] > 0 and result["payload_bytes"] > 0
