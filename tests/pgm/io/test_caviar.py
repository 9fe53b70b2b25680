"""The CAVIAR XML ground-truth reader against a hand-written fixture."""

from pathlib import Path

import numpy as np
import pytest

from pgm.core.errors import InputError
from pgm.evaluation.mot import evaluate_mot
from pgm.io.annotations import load_caviar, load_mot

FIXTURE = Path(__file__).parent / "data" / "caviar_small.xml"


def test_reads_boxes_identities_and_frames():
    t = load_caviar(FIXTURE)
    assert t.frames.tolist() == [1, 2, 2]  # CAVIAR frame 0 is frame 1
    assert t.ids.tolist() == [0, 0, 4]
    np.testing.assert_allclose(t.boxes, [[90, 50, 20, 60], [93, 51, 20, 60],
                                         [191, 95, 18, 50]])
    assert t.scored.all() and not t.ignore.any()
    # load_mot reads it as ground truth, so every tool that takes --gt does
    assert load_mot(FIXTURE, kind="gt").ids.tolist() == [0, 0, 4]


def test_scores_against_itself():
    t = load_caviar(FIXTURE)
    m = evaluate_mot(t, t, num_frames=3)
    assert m["mota"] == 1.0 and m["idf1"] == 1.0


@pytest.mark.parametrize("text, match", [
    ("not xml at all", "not a CAVIAR XML"),
    ("<dataset/>", "no <frame>"),
    ('<dataset><frame number="a"/></dataset>', "integer number"),
    ('<dataset><frame number="0"><objectlist><object><box xc="1" yc="1" w="2" h="2"/>'
     '</object></objectlist></frame></dataset>', "integer id"),
    ('<dataset><frame number="0"><objectlist><object id="1"><box xc="1" yc="1" w="2"/>'
     '</object></objectlist></frame></dataset>', "needs numbers"),
    ('<dataset><frame number="0"><objectlist><object id="1"><box xc="1" yc="1" w="0" h="2"/>'
     '</object></objectlist></frame></dataset>', "not finite and positive"),
    ('<dataset><frame number="0"><objectlist><object id="1"><box xc="1" yc="1" w="2" h="2"/>'
     '</object><object id="1"><box xc="1" yc="1" w="2" h="2"/></object></objectlist></frame>'
     '</dataset>', "twice"),
])
def test_malformed_files_are_one_line_errors(tmp_path, text, match):
    p = tmp_path / "gt.xml"
    p.write_text(text)
    with pytest.raises(InputError, match=match):
        load_caviar(p)
