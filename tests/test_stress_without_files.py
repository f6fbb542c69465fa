"""``stress`` without ``--json`` and ``--out`` runs and prints its table and verdict, writing no file (the
README's second stress command); with one of them it writes that one only."""

from autoscoop.cli import main

SMALL = ["--episodes", "1", "--cases", "nominal,heavy", "--set", "pile.variants=1"]


def test_stress_prints_the_table_without_json_or_out(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["stress", "--policy", "heuristic", *SMALL]) == 0
    printed = capsys.readouterr().out
    assert "nominal" in printed and "heavy" in printed and "wrote" not in printed
    assert list(tmp_path.iterdir()) == []


def test_stress_writes_only_the_json_it_is_given(tmp_path, capsys):
    out = tmp_path / "stress.json"
    assert main(["stress", "--policy", "heuristic", *SMALL, "--json", str(out)]) == 0
    assert out.is_file() and sorted(p.name for p in tmp_path.iterdir()) == ["stress.json"]
    assert f"wrote {out}" in capsys.readouterr().out
