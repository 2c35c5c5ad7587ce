"""The sensitivity study's variants change what they say they change."""

from __future__ import annotations

from softevo.analysis import sensitivity


def _scene() -> dict:
    return {"body": [[[2, 2], [1, 1]]], "material": {"youngs_modulus": 1e6},
            "environment": {"kind": "land"}, "duration": {"seconds": 0.3},
            "settle_seconds": 0.0}


def test_low_damping_reaches_the_simulator(monkeypatch):
    seen = []
    real = sensitivity.sim.simulate_many

    def spy(scenes, **options):
        seen.extend(scenes)
        return real(scenes, **options)

    monkeypatch.setattr(sensitivity.sim, "simulate_many", spy)
    damped = sensitivity.sim.simulate(_scene())
    (light,) = sensitivity.with_damping(sensitivity.LOW_DAMPING)([_scene()])
    assert seen[-1]["material"]["damping_global"] == sensitivity.LOW_DAMPING
    assert seen[-1]["material"]["youngs_modulus"] == 1e6  # the rest of the material kept
    assert light.distance != damped.distance  # the physics sees it


def test_a_tiny_study_prints_its_table(capsys):
    code = sensitivity.main(["--stiffness", "0.1", "--repetitions", "1", "--generations", "1",
                             "--population", "2", "--workspace", "3", "--cycles", "1",
                             "--variants", "damping,frequency"])
    out = capsys.readouterr().out
    assert code == 0
    assert "| damping | land |" in out and "| frequency | water |" in out


def test_bad_input_is_one_line_and_status_2(capsys):
    assert sensitivity.main(["--stiffness", "soft"]) == 2
    assert sensitivity.main(["--variants", "gravity"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(line.startswith("error:") for line in err)
