"""Which motion-mode model the service applies to a placement group (classifiers.installed.placement_model)."""

from __future__ import annotations


def test_placement_model_is_the_shipped_pocket_model_and_none_for_uninstalled_ones(tmp_path, monkeypatch):
    from classifiers import installed

    assert installed.placement_model("pocket") == "motion_mode"
    assert installed.placement_model("swinging") is None
    monkeypatch.setattr(installed, "MODELS_DIR", tmp_path)
    assert installed.placement_model("hand") is None
    (tmp_path / "motion_mode_hand").mkdir()
    (tmp_path / "motion_mode_hand" / "model.json").write_text("{}", encoding="utf-8")
    assert installed.placement_model("hand") == "motion_mode_hand"
