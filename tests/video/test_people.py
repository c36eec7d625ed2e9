"""Several people from video (``mocap detect --people``): finding people by searching again with
the found ones blacked out, following each in its own crop with stable per-view ids, grouping
them across views for the per-person left/right check, the folder read back with several people
per frame, ``--people 1`` unchanged, and bad values refused before any work.

The logic is checked with a stand-in one-person pose model (the largest bright blob of the
image: like BlazePose, it returns one person, the most salient); the real model on two people
of the Pose2Sim demo pasted side by side at known places; and on the real two-person recording
(skipped without mediapipe or the data)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from mocap.cameras import project, rig_from_config, triangulate
from mocap.data.openpose import load_openpose_sequence
from mocap.video.detect import MIRROR, left_right_fixes
from mocap.video.detector import detector_available
from mocap.video.people import (
    PeopleDetector,
    PeopleSettings,
    black_out,
    box_iou,
    crop_box,
    hidden_pixels,
    keypoint_boxes,
    keypoint_distance,
    parse_people,
    shown_keypoints,
    split_masks,
)
from mocap.video.people_views import group_views
from mocap_cli.main import main as cli
from tests.video.test_detect import stick_figure_keypoints

needs_detector = pytest.mark.skipif(not detector_available(),
                                    reason="mediapipe not installed (scripts/setup_env.sh installs it)")
SHARED = Path(os.environ.get("MOCAP_SHARED_DATA",
                             Path(__file__).resolve().parents[2].parent / "shared" / "data"))


# --- a stand-in one-person model: the largest bright blob ---------------------------------------

def blob_pose(rgb: np.ndarray):
    """(33, 3) keypoints spread over the largest blob of person-grey (200) pixels' box (a
    3 x 11 grid), its mask. The blurred fill that hides found people is darker."""
    fg = (rgb.max(axis=2) > 190).astype(np.uint8)
    n, lab, stats, _ = cv2.connectedComponentsWithStats(fg)
    if n < 2:
        return None
    k = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    x, y, w, h = stats[k, :4]
    gx, gy = np.meshgrid(np.linspace(x, x + w - 1, 3), np.linspace(y, y + h - 1, 11))
    kp = np.column_stack([gx.ravel(), gy.ravel(), np.full(33, 0.9)])
    return kp, (lab == k).astype(np.float32)


def scene(boxes, size=(240, 320)) -> np.ndarray:
    """(H, W, 3) black image with a grey filled rectangle per box (x0, y0, x1, y1 inclusive)."""
    img = np.zeros((*size, 3), np.uint8)
    for x0, y0, x1, y1 in boxes:
        img[y0:y1 + 1, x0:x1 + 1] = 200
    return img


def test_box_iou_and_crop_against_hand_computed_values():
    a = np.array([[0, 0, 10, 10]])
    b = np.array([[5, 0, 15, 10], [20, 20, 30, 30], [0, 0, 10, 10]])
    assert np.allclose(box_iou(a, b), [[50 / 150, 0.0, 1.0]])
    assert crop_box(np.array([40, 20, 60, 80]), 0.25, 100, 200) == (5, 5, 95, 95)   # 60 tall -> 90 square
    assert crop_box(np.array([0, 0, 20, 40]), 0.25, 100, 200) == (0, 0, 40, 50)     # clipped at the edges
    kp = np.array([[1, 2, 0.9], [5, 9, 0.8], [100, 100, 0.1]])
    assert np.array_equal(keypoint_boxes(kp, 0.5), [1, 2, 5, 9])              # the low one left out


def test_keypoint_distance_is_the_median_shift_over_the_height_whatever_the_boxes_overlap():
    a = np.zeros((33, 3))
    a[:, 0], a[:, 1], a[:, 2] = 50, np.linspace(0, 100, 33), 0.9          # 100 px tall
    b = a.copy()
    b[:, 0] += 10                                                          # same box size, 10 px right
    b[10:13, 2] = 0.1                                                      # three not shared
    d = keypoint_distance(np.stack([a, b]), np.stack([a, b]))
    assert np.allclose(d, [[0, 0.1], [0.1, 0]])
    few = a.copy()
    few[2:, 2] = 0
    assert np.isinf(keypoint_distance(few[None], a[None]))[0, 0]            # fewer than 3 shared


def test_split_masks_gives_each_overlapping_pixel_to_the_nearer_skeleton_within_reach():
    """Two upright people at x = 40 and x = 80 (120 px tall) whose masks both cover both bodies
    (BlazePose segments everyone in a crop): each keeps the pixels nearer its own bones, and,
    with reach 0.1, none farther than 0.1 x 120 = 12 px from them."""
    def stick(x):
        kp = np.zeros((33, 3))
        kp[:, 0], kp[:, 1], kp[:, 2] = x, np.linspace(10, 130, 33), 0.9
        return kp
    both = np.zeros((140, 120), np.float32)
    both[10:131, 30:91] = 1.0
    a, b = split_masks([both, both], [stick(40), stick(80)], reach=1.0, step=1)
    assert not (a.astype(bool) & b.astype(bool)).any() and np.array_equal(a + b, both)
    assert a[70, 59] == 1 and b[70, 61] == 1 and a[70, 61] == 0 and b[70, 59] == 0   # split half way
    a, b = split_masks([both, both], [stick(40), stick(80)], reach=0.1, step=1)
    # 12 px from the drawn bones (their points are discs of radius 1 grid cell: x 39-41, 79-81)
    assert a[70, 53] == 1 and a[70, 54] == 0 and b[70, 67] == 1 and b[70, 66] == 0
    assert a[70, 30] == 1 and b[70, 90] == 1


def test_black_out_hides_boxes_grown_by_their_fraction_and_masks_with_a_darker_fill():
    img = np.full((100, 200, 3), 200, np.uint8)
    out = black_out(img, [], [np.array([50.0, 20.0, 90.0, 60.0])], grow=0.1)   # 40 x 40, +4 px a side
    dark = np.all(out == 0, axis=2)
    ys, xs = np.nonzero(dark)
    assert (xs.min(), xs.max(), ys.min(), ys.max()) == (46, 94, 16, 64) and dark.sum() == 49 * 49
    person = np.zeros((100, 200), np.float32)
    person[30:70, 20:40] = 1.0
    img[30:70, 20:40] = 255                                                    # a bright person on grey
    hidden = black_out(img, [person], [])
    assert hidden[30:70, 20:40].max() < 250 and np.array_equal(hidden[:, 100:], img[:, 100:])


def test_two_people_found_at_their_boxes_by_searching_again_with_the_first_blacked_out():
    boxes = [(20, 30, 80, 200), (200, 40, 250, 190)]          # the larger (found first) on the left
    det = PeopleDetector(PeopleSettings(people=2), pose=blob_pose)
    found = det(scene(boxes))
    assert [p.id for p in found] == [0, 1]
    got = np.stack([keypoint_boxes(p.keypoints) for p in found])
    assert np.allclose(got, boxes)
    assert np.array_equal(found[1].mask > 0.5, scene([boxes[1]])[..., 0] > 0)
    one = PeopleDetector(PeopleSettings(people=1), pose=blob_pose)(scene(boxes))
    assert len(one) == 1 and np.allclose(keypoint_boxes(one[0].keypoints), boxes[0])
    auto = PeopleDetector(PeopleSettings(people=None), pose=blob_pose)(scene(boxes + [(120, 100, 140, 130)]))
    assert len(auto) == 3                               # everyone, and the search stops when none is left


def test_per_view_ids_follow_each_person_over_frames_even_when_the_larger_one_changes():
    """The left person shrinks and the right one grows (the stand-in model's first pick
    changes at frame 5) while both walk: each id stays on its own person."""
    det = PeopleDetector(PeopleSettings(people=2), pose=blob_pose)
    for f in range(10):
        left = (20 + 3 * f, 30, 90 + 3 * f - 6 * f, 200)
        right = (180 - 2 * f, 60 - 4 * f, 230 - 2 * f + 2 * f, 150 + 4 * f)
        found = det(scene([left, right]))
        by_id = {p.id: keypoint_boxes(p.keypoints) for p in found}
        assert sorted(by_id) == [0, 1], f
        assert np.allclose(by_id[0], left) and np.allclose(by_id[1], right), (f, by_id)


def test_shown_keypoints_count_the_confident_ones_inside_the_image_and_not_hidden():
    kp = np.array([[5, 5, 0.9], [15, 5, 0.9], [25, 5, 0.9], [35, 5, 0.2], [-3, 5, 0.9], [5, 25, 0.9]])
    hidden = np.zeros((20, 40), bool)
    hidden[:, 10:20] = True
    # confident and inside: x 5, 15, 25 (y 5); x 35 is unconfident, x -3 and y 25 off the image
    assert shown_keypoints(kp, hidden) == (3, 2)
    assert hidden_pixels((20, 40), [], [np.array([10.0, 0.0, 19.0, 19.0])], grow=0.0)[:, 10:20].all()


def leftover_pose(a_body, a_arm, b_body):
    """A stand-in pose model that behaves as BlazePose did on the real recording with ``auto``:
    person A (box ``a_body``) is found with a mask that misses its arm (``a_arm``); once A is
    hidden, the arm still shows and the model completes a whole body over the hidden pixels
    (30 keypoints over A's place, 3 on the arm); person B (``b_body``) is found once
    nothing else draws the model. Boxes x0, y0, x1, y1 inclusive; found: grey (200) pixels."""
    def grid(box, n_x=3, n_y=11):
        x0, y0, x1, y1 = box
        gx, gy = np.meshgrid(np.linspace(x0, x1, n_x), np.linspace(y0, y1, n_y))
        return np.column_stack([gx.ravel(), gy.ravel(), np.full(n_x * n_y, 0.9)])

    def shows(rgb, box):
        x0, y0, x1, y1 = box
        return (rgb[y0:y1 + 1, x0:x1 + 1].max(axis=2) > 190).mean() > 0.5

    def mask(rgb, box):
        m = np.zeros(rgb.shape[:2], np.float32)
        m[box[1]:box[3] + 1, box[0]:box[2] + 1] = 1.0
        return m

    def run(rgb):
        if shows(rgb, a_body):
            return grid(a_body), mask(rgb, a_body)
        if shows(rgb, a_arm):
            x0, y0, x1, y1 = a_body
            w, h = x1 - x0, y1 - y0               # made up: A's place, shifted half a width, shorter
            made_up = grid((x0 + w // 2, y0 + h // 4, x1 + w // 2, y1), 3, 10)
            arm = np.array([[a_arm[0], a_arm[1], 0.9], [(a_arm[0] + a_arm[2]) / 2, a_arm[1], 0.9],
                            [a_arm[2], a_arm[1], 0.9]])
            return np.vstack([made_up, arm]), mask(rgb, a_arm)
        if shows(rgb, b_body):
            return grid(b_body), mask(rgb, b_body)
        return None

    return run


def test_leftover_parts_completed_over_hidden_pixels_make_no_person():
    a_body, a_arm, b_body = (20, 30, 80, 200), (81, 90, 150, 98), (220, 40, 280, 200)
    image = scene([a_body, a_arm, b_body])
    det = PeopleDetector(PeopleSettings(people=None), pose=leftover_pose(a_body, a_arm, b_body))
    found = det(image)
    assert len(found) == 2 and det.leftovers == 1          # A and B; the arm's made-up body refused
    boxes = np.stack([keypoint_boxes(p.keypoints) for p in found])
    assert np.allclose(boxes, [a_body, b_body])
    # without the rule (every find a person) the leftover is a third person
    every = PeopleDetector(PeopleSettings(people=None, min_keypoints=1, min_shown=0.0),
                           pose=leftover_pose(a_body, a_arm, b_body))
    assert len(every(image)) == 3 and every.leftovers == 0


def test_a_frame_of_another_size_is_refused_with_one_line():
    det = PeopleDetector(PeopleSettings(people=2), pose=blob_pose)
    det(scene([(20, 30, 80, 200)]))
    with pytest.raises(ValueError, match="frame of 160x120 after frames of 320x240"):
        det(scene([(20, 30, 80, 100)], size=(120, 160)))


def test_a_person_who_leaves_and_comes_back_keeps_its_id_and_a_newcomer_gets_a_new_one():
    det = PeopleDetector(PeopleSettings(people=None, lost_after=3, search_every=1), pose=blob_pose)
    a, b = (20, 30, 80, 200), (200, 40, 250, 190)
    assert [p.id for p in det(scene([a, b]))] == [0, 1]
    assert [p.id for p in det(scene([a]))] == [0]                      # b hidden for one frame
    assert [p.id for p in det(scene([a, b]))] == [0, 1]                # back: its own id
    for _ in range(4):
        det(scene([a]))                                                # b gone longer than lost_after
    assert [p.id for p in det(scene([a, (190, 40, 240, 190)]))] == [0, 2]   # a new id, never reused


def test_views_grouped_per_person_and_each_persons_swapped_view_mirrored_back():
    rig = rig_from_config("ring4_small")
    one = stick_figure_keypoints(rig, seed=0)                          # (C, 33, 3) at the origin
    other = stick_figure_keypoints(rig, seed=1)                        # moved 0.8 m along x:
    idx = np.flatnonzero(other[0, :, 2] > 0)
    X = triangulate(rig, other[:, idx, :2]) + np.array([0.8, 0.0, 0.0])
    other[:, idx, :2] = project(rig, X)
    order = [(0, 1), (1, 0), (0, 1), (1, 0)]                           # the detector's order per view
    people = [np.stack([(one, other)[k][c] for k in order[c]]) for c in range(len(rig))]
    groups = group_views(rig, people)
    truth = [{c: order[c].index(0) for c in range(4)}, {c: order[c].index(1) for c in range(4)}]
    assert sorted(groups, key=lambda g: g[0]) == sorted(truth, key=lambda g: g[0])
    people[2][order[2].index(1)] = people[2][order[2].index(1)][MIRROR]    # person 1 mirrored in view 2
    mirrored = []
    for g in group_views(rig, people):
        kp = np.zeros((4, 33, 3))
        for c, i in g.items():
            kp[c] = people[c][i]
        mirrored.append((sorted(g.items()), left_right_fixes(rig, kp)))
    who = {tuple(items): fixed for items, fixed in mirrored}
    assert who[tuple(sorted(truth[1].items()))] == [2] and who[tuple(sorted(truth[0].items()))] == []


# --- bad input: one line, before any work (no detector needed) -----------------------------------

@pytest.mark.parametrize("value", ["0", "-2", "1.5", "two", ""])
def test_bad_people_value_refused_with_one_line_before_any_work(value, tmp_path, capsys):
    out = tmp_path / "out"
    code = cli(["detect", str(tmp_path / "no-such-recording"), "--out", str(out), "--people", value,
                "--no-progress"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "--people" in err and repr(value) in err, err
    assert not out.exists()


def test_parse_people_accepts_whole_numbers_and_auto():
    assert parse_people("3") == 3 and parse_people(2) == 2 and parse_people("auto") is None
    assert parse_people(" AUTO ") is None
    for bad in (0, -1, 1.0, True, "1e3", None):
        with pytest.raises(ValueError, match="whole number >= 1 or 'auto'"):
            parse_people(bad)


# --- the real model ---------------------------------------------------------------------------------

def demo_subject_crop(n: int, margin: float = 0.12) -> tuple[np.ndarray, np.ndarray]:
    """Frame n of the single-person demo's cam01, cropped around its subject (the larger
    OpenPose skeleton of the demo's own keypoint files): (crop RGB, the subject's box in it)."""
    demo = SHARED / "pose2sim-demo"
    people = json.loads((demo / "pose" / "cam01_json" / f"cam01.{n:04d}.json").read_text())["people"]
    kps = [np.reshape(p["pose_keypoints_2d"], (-1, 3)) for p in people]
    for k in kps:
        k[(k[:, 0] <= 0) | (k[:, 1] <= 0), 2] = 0                 # (0, 0): not found, whatever its score
    boxes = [keypoint_boxes(k, 0.3) for k in kps]
    box = max(boxes, key=lambda b: b[3] - b[1])
    cap = cv2.VideoCapture(str(demo / "videos" / "cam01.mp4"))
    cap.set(cv2.CAP_PROP_POS_FRAMES, n)
    ok, bgr = cap.read()
    cap.release()
    assert ok
    w, h = box[2] - box[0], box[3] - box[1]
    x0, y0 = int(max(0, box[0] - margin * w)), int(max(0, box[1] - margin * h))
    x1, y1 = int(min(bgr.shape[1], box[2] + margin * w)), int(min(bgr.shape[0], box[3] + margin * h))
    return bgr[y0:y1, x0:x1, ::-1].copy(), box - np.array([x0, y0, x0, y0])


needs_demo = pytest.mark.skipif(not (SHARED / "pose2sim-demo" / "videos" / "cam01.mp4").is_file(),
                                reason="the Pose2Sim demo is not in ../shared/data")


@needs_detector
@needs_demo
@pytest.mark.slow
def test_blazepose_finds_two_pasted_people_at_their_known_boxes_with_stable_ids():
    """Two crops of the demo's subject (frames n and n + 80: two poses) pasted side by side on
    grey, over 4 frames: 2 people every frame, each id's keypoint box overlapping its own
    pasted person's known box (IoU >= 0.6; BlazePose's and OpenPose's keypoints differ: feet,
    ears) and never the other one."""
    det = PeopleDetector(PeopleSettings(people=2))
    seen = {}
    try:
        for n in range(0, 8, 2):
            (a, box_a), (b, box_b) = demo_subject_crop(n), demo_subject_crop(n + 80)
            canvas = np.full((1200, 1000, 3), 128, np.uint8)                 # one size, as a video's frames
            canvas[:len(a), :a.shape[1]] = a
            x_b = 1000 - b.shape[1]
            assert x_b >= a.shape[1] + 60                                      # apart
            canvas[:len(b), x_b:] = b
            known = np.stack([box_a, box_b + np.array([x_b, 0, x_b, 0])])
            found = det(canvas)
            assert len(found) == 2, n
            iou = box_iou(np.stack([keypoint_boxes(p.keypoints) for p in found]), known)
            side = iou.argmax(axis=1)
            assert sorted(side) == [0, 1] and iou.max(axis=1).min() >= 0.6, (n, iou.round(2))
            for p, s in zip(found, side, strict=True):
                assert seen.setdefault(p.id, s) == s                    # the id stays on its side
    finally:
        det.close()


MULTI = SHARED / "pose2sim-demo-multi"
needs_multi = pytest.mark.skipif(not (MULTI / "Calib.toml").is_file(),
                                 reason="pose2sim-demo-multi is not in ../shared/data")


@needs_detector
@pytest.mark.slow
@needs_multi
def test_real_two_person_recording_both_people_in_every_view_read_back_with_two_people(tmp_path, capsys):
    out = tmp_path / "multi"
    assert cli(["detect", str(MULTI), "--out", str(out), "--people", "2", "--stop", "10", "--scale", "0.5",
                "--no-progress"]) == 0
    head = json.loads((out / "detect.json").read_text())
    assert head["people"] == 2
    for name, v in head["views"].items():
        assert v["people_per_frame"] == [2] * 10 and v["person_ids"] == [0, 1], (name, v)
        rec = json.loads((out / "detect" / f"{name}.json").read_text())
        assert rec["settings"]["people"] == 2
        for pid in (0, 1):
            assert len(list((out / "masks" / name / str(pid)).glob("*.png"))) == 10
    seq = load_openpose_sequence(out, layout="auto", person="all")
    assert seq.meta["layout"] == "MEDIAPIPE_33" and seq.num_frames == 10
    d = seq.detections
    for f in range(10):
        for c in range(seq.num_views):
            sel = d.select(f, c)
            assert len(np.unique(sel.person)) == 2, (f, c)
    capsys.readouterr()


@needs_detector
@pytest.mark.slow
@needs_multi
def test_real_two_person_recording_with_people_auto_gives_two_tracks_and_no_leftover_skeletons(body, tmp_path,
                                                                                                capsys):
    """--people auto on frames 60-69 at half size (the actors close together in cam_03): at most
    2 people a frame in every view, and marker_people makes exactly the 2 actors' tracks, both
    from the first frame to the last. (This short run found no leftover skeletons before the
    leftover rule either: they appeared after 30 frames of following at full size,
    docs/results/people_from_video.md; the rule itself is checked with the stand-in above.)"""
    from mocap.trackers.presets import make_tracker
    from mocap.trackers.run import frame_of

    out = tmp_path / "auto"
    assert cli(["detect", str(MULTI), "--out", str(out), "--people", "auto", "--start", "60", "--stop", "70",
                "--scale", "0.5", "--no-progress"]) == 0
    head = json.loads((out / "detect.json").read_text())
    for name, v in head["views"].items():
        assert max(v["people_per_frame"]) <= 2, (name, v["people_per_frame"])
    seq = load_openpose_sequence(out, layout="auto", person="all")
    people = make_tracker("marker_people", body=body, rig=seq.rig, rng=np.random.default_rng(0),
                          particles=30, layers=3, init={"particles": 60, "passes": 2, "layers": 5})
    people.check_sequence(seq)
    people.start(frame_of(seq, 0))
    for f in range(1, seq.num_frames):
        people.step(frame_of(seq, f))
    assert people.births == {0: [0, 1]} and people.deaths == {}
    assert all(len(t.estimates) == seq.num_frames for t in people.tracks)
    capsys.readouterr()


@needs_detector
@pytest.mark.slow
@needs_multi
def test_people_1_writes_the_same_files_as_before(tmp_path):
    """--people 1 is the one-person detector of before: byte-identical keypoints, masks, view
    records and detect.json to a run without the flag."""
    runs = []
    for extra in ([], ["--people", "1"]):
        out = tmp_path / f"run{len(runs)}"
        assert cli(["detect", str(MULTI), "--out", str(out), "--stop", "3", "--scale", "0.25",
                    "--no-progress", *extra]) == 0
        runs.append(out)
    a, b = runs
    files = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file() and p.suffix in (".json", ".png"))
    assert len(files) > 20
    for rel in files:
        ta, tb = (a / rel).read_bytes(), (b / rel).read_bytes()
        if rel.name == "detect.json" or rel.parent.name == "detect":          # seconds per frame differ
            ja, jb = json.loads(ta), json.loads(tb)
            for j in (ja, jb):
                j.pop("seconds_per_frame", None)
                for v in j.get("views", {}).values():
                    v.pop("seconds_per_frame")
            assert ja == jb and "people" not in ja and "people" not in ja.get("settings", {}), rel
        else:
            assert ta == tb, rel
