import json

import numpy as np
import pytest

from softevo.service.cli import main


def write(tmp_path, scene):
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    return str(path)


def test_describe_json(tmp_path, capsys):
    body = np.zeros((3, 3, 1), dtype=int)
    body[1, :] = 2
    body[:, 1] = 1
    main(
        [
            "describe",
            write(tmp_path, {"body": body.tolist(), "actuation": {"frequency": 2.0}}),
            "--json",
        ]
    )
    out = json.loads(capsys.readouterr().out)
    assert out["voxel_count"] == 5 and out["branching"] == pytest.approx(2 / 7)
    assert out["frequency"] == 2.0 and out["active_share"] == pytest.approx(0.4)
    assert set(out) == {
        "symmetry",
        "branching",
        "shape_entropy",
        "voxel_count",
        "active_share",
        "frequency",
    }


@pytest.mark.parametrize(
    "content",
    [
        "{not json",
        json.dumps({"body": [[[0]]]}),
        json.dumps({"body": [[[1]]], "material": {"youngs_modulus": -1}}),
    ],
)
def test_describe_bad_input_exits_2_with_one_line(tmp_path, capsys, content):
    path = tmp_path / "scene.json"
    path.write_text(content)
    with pytest.raises(SystemExit) as exit_info:
        main(["describe", str(path)])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and "\n" not in err
