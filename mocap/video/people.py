"""Several people per view with a one-person pose model: find people by searching the image
again with the people already found blacked out, then follow each one with the pose model run
on a crop around its previous keypoints (the other people's previous masks blacked out in the
crop), and keep per-view person ids over time by box overlap.

    detector = PeopleDetector(PeopleSettings(people=2))     # or people=None: everyone (auto)
    found = detector(rgb)                                   # rgb (H, W, 3) uint8, one view's frames in order
    found[0].id, found[0].keypoints, found[0].mask          # (33, 3) image pixels, (H, W) probability
    detector.close()

BlazePose (the model shipped in the mediapipe wheel, :mod:`mocap.video.detector`) returns one
person per image: the one its person detector scores highest. Black out that person (its mask
and its keypoints' box) and the next-best person is found, until none is left or enough are
found. This needs no other model and no other package. The cross-view association of the
per-view people is the several-people tracker's job (``tracker=marker_people``);
:func:`mocap.video.people_views.group_views` associates them per frame for the left/right
check only.

A search's find is a person only when the image showed it: BlazePose, given an image with the
people found hidden, also finds what is left of them (an arm or the legs outside their masks)
and completes a whole body over the hidden pixels. A find with fewer than ``min_keypoints``,
or less than ``min_shown`` of its confident keypoints, on pixels the search image shows is
refused as such leftover parts (``PeopleDetector.leftovers`` counts them).

Limits (docs/results/people_from_video.md): where two people overlap in a view, BlazePose mixes
them or finds one; a small person far in the background is found only when BlazePose's
whole-image detector picks them.
"""

from __future__ import annotations

import contextlib
import io
from collections.abc import Callable
from dataclasses import dataclass, field

import cv2
import numpy as np

from mocap.video.detector import NUM_KEYPOINTS, DetectorSettings, _import_mediapipe

#: the value of ``people`` that means "everyone found" (capped by PeopleSettings.max_people)
AUTO = "auto"


def parse_people(value: object, where: str = "people") -> int | None:
    """``people`` as given (an int >= 1, a digit string, or "auto") -> an int, or None for
    auto. Raises ValueError naming ``where`` and the value."""
    given = value
    if isinstance(value, str):
        text = value.strip().lower()
        if text == AUTO:
            return None
        if text.lstrip("+").isdigit():
            value = int(text)
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{where} must be a whole number >= 1 or 'auto', got {given!r}")
    return int(value)


@dataclass(frozen=True)
class PeopleSettings:
    people: int | None = 1               # people per view to follow; None: everyone found (auto)
    max_people: int = 8                  # auto: at most this many per view
    search_every: int = 10               # auto: frames between searches for more people
    min_keypoints: int = 8               # keypoints with confidence >= min_confidence for a person to count
    min_shown: float = 0.75              # a search's find: at least min_keypoints and this fraction of them
    #                                      on pixels the search image shows (else: leftover parts of people
    #                                      found, completed by the model over the hidden ones)
    min_confidence: float = 0.5
    margin: float = 0.3                  # crop: the last keypoints' box grown by this x its size per side
    lost_after: int = 15                 # frames a person may go unseen before its id is retired
    same_distance: float = 0.15          # keypoints this close (median, x the person's height): one person
    new_iou: float = 0.3                 # a find overlapping a lost person's last box more: that person
    detector: DetectorSettings = field(default_factory=DetectorSettings)

    def __post_init__(self):
        if self.people is not None:
            parse_people(self.people)
        if not 0 <= self.min_shown <= 1:
            raise ValueError(f"people settings min_shown must be in [0, 1], got {self.min_shown!r}")
        for name in ("max_people", "search_every", "min_keypoints", "lost_after"):
            if getattr(self, name) < 1:
                raise ValueError(f"people settings {name} must be >= 1, got {getattr(self, name)!r}")

    @property
    def wanted(self) -> int:
        return self.max_people if self.people is None else self.people


@dataclass(frozen=True)
class Person:
    """One person in one image: per-view id (stable over the view's frames), keypoints
    (33, 3) x, y in pixels of the image (pixel centres), confidence; mask (H, W) float32
    person probability (zeros without the segmentation head)."""

    id: int
    keypoints: np.ndarray
    mask: np.ndarray


def keypoint_boxes(kp: np.ndarray, min_confidence: float = 0.5) -> np.ndarray:
    """(..., K, 3) keypoints -> (..., 4) boxes x0, y0, x1, y1 of those with confidence >=
    ``min_confidence`` (all NaN where none is)."""
    ok = kp[..., 2] >= min_confidence
    x = np.where(ok, kp[..., 0], np.nan)
    y = np.where(ok, kp[..., 1], np.nan)
    with np.errstate(all="ignore"), _quiet_nan():
        return np.stack([np.nanmin(x, -1), np.nanmin(y, -1), np.nanmax(x, -1), np.nanmax(y, -1)], -1)


@contextlib.contextmanager
def _quiet_nan():
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        yield


def keypoint_distance(a: np.ndarray, b: np.ndarray, min_confidence: float = 0.5) -> np.ndarray:
    """(N, K, 3), (M, K, 3) -> (N, M): median distance between the same keypoints (those with
    confidence >= ``min_confidence`` in both), divided by the mean of the two people's
    keypoint heights; inf where fewer than 3 keypoints are shared. Two finds of one body are
    near 0 however much two people's boxes overlap."""
    ok = (a[:, None, :, 2] >= min_confidence) & (b[None, :, :, 2] >= min_confidence)       # (N, M, K)
    d = np.linalg.norm(a[:, None, :, :2] - b[None, :, :, :2], axis=-1)
    ha = np.diff(keypoint_boxes(a, min_confidence)[:, [1, 3]], axis=1)[:, 0]
    hb = np.diff(keypoint_boxes(b, min_confidence)[:, [1, 3]], axis=1)[:, 0]
    with np.errstate(all="ignore"), _quiet_nan():
        med = np.nanmedian(np.where(ok, d, np.nan), axis=-1) / ((ha[:, None] + hb[None]) / 2)
    return np.where((ok.sum(-1) >= 3) & np.isfinite(med), med, np.inf)


def box_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, 4), (M, 4) boxes x0, y0, x1, y1 -> (N, M) intersection over union (0 where NaN)."""
    a, b = np.asarray(a, float)[:, None], np.asarray(b, float)[None]
    w = np.clip(np.minimum(a[..., 2], b[..., 2]) - np.maximum(a[..., 0], b[..., 0]), 0, None)
    h = np.clip(np.minimum(a[..., 3], b[..., 3]) - np.maximum(a[..., 1], b[..., 1]), 0, None)
    inter = w * h
    area = lambda q: (q[..., 2] - q[..., 0]) * (q[..., 3] - q[..., 1])      # noqa: E731
    with np.errstate(all="ignore"):
        out = inter / (area(a) + area(b) - inter)
    return np.nan_to_num(out, nan=0.0)


def crop_box(box: np.ndarray, margin: float, width: int, height: int) -> tuple[int, int, int, int]:
    """Integer crop x0, y0, x1, y1 (exclusive) around ``box``: grown by ``margin`` x its size
    per side, then to a square (BlazePose's detector works on square inputs) clipped to the image."""
    x0, y0, x1, y1 = box
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    side = max(x1 - x0, y1 - y0) * (1 + 2 * margin)
    half = max(side / 2, 16.0)
    return (int(max(0, np.floor(cx - half))), int(max(0, np.floor(cy - half))),
            int(min(width, np.ceil(cx + half))), int(min(height, np.ceil(cy + half))))


def _mask_hidden(masks: list[np.ndarray], H: int, W: int) -> np.ndarray:
    """(H, W) bool: the masks (probability >= 0.5) dilated by 1 % of the image."""
    hide = np.any([m >= 0.5 for m in masks], axis=0).astype(np.uint8)
    size = max(3, int(0.01 * max(H, W))) | 1
    return cv2.dilate(hide, np.ones((size, size), np.uint8)).astype(bool)


def _box_slices(b: np.ndarray, grow: float, H: int, W: int) -> tuple[slice, slice] | None:
    if not np.all(np.isfinite(b)):
        return None
    gw, gh = grow * (b[2] - b[0]), grow * (b[3] - b[1])
    x0, y0 = int(max(0, b[0] - gw)), int(max(0, b[1] - gh))
    x1, y1 = int(min(W, b[2] + gw + 1)), int(min(H, b[3] + gh + 1))
    return slice(y0, y1), slice(x0, x1)


def hidden_pixels(shape: tuple[int, int], masks: list[np.ndarray], boxes: list[np.ndarray],
                  grow: float = 0.1) -> np.ndarray:
    """(H, W) bool: the pixels :func:`black_out` hides (its masks, dilated, and boxes, grown)."""
    H, W = shape
    out = _mask_hidden(masks, H, W) if masks else np.zeros((H, W), bool)
    for b in boxes:
        sl = _box_slices(b, grow, H, W)
        if sl is not None:
            out[sl] = True
    return out


def black_out(rgb: np.ndarray, masks: list[np.ndarray], boxes: list[np.ndarray], grow: float = 0.1
              ) -> np.ndarray:
    """A copy of ``rgb`` with the people already found hidden from the next search: each
    mask (probability >= 0.5, dilated by 1 % of the image) filled with a heavily blurred copy
    of the image (black would leave a person-shaped silhouette that the person detector
    finds again), each box (grown by ``grow`` x its size per side) set to black."""
    out = rgb.copy()
    H, W = rgb.shape[:2]
    if masks:
        hide = _mask_hidden(masks, H, W)
        small = cv2.resize(rgb, (max(1, W // 16), max(1, H // 16)), interpolation=cv2.INTER_AREA)
        fill = cv2.resize(cv2.GaussianBlur(small, (0, 0), 2), (W, H), interpolation=cv2.INTER_LINEAR)
        out[hide] = fill[hide]
    for b in boxes:
        sl = _box_slices(b, grow, H, W)
        if sl is not None:
            out[sl] = 0
    return out


def shown_keypoints(kp: np.ndarray, hidden: np.ndarray, min_confidence: float = 0.5) -> tuple[int, int]:
    """(keypoints with confidence >= ``min_confidence`` inside the image, those of them on
    pixels not ``hidden`` (H, W)) of one find ``kp`` (K, 3) in image pixels: what the image
    showed of it, against what the pose model completed over hidden pixels."""
    H, W = hidden.shape
    x, y = np.round(kp[:, 0]).astype(np.int64), np.round(kp[:, 1]).astype(np.int64)
    inside = (kp[:, 2] >= min_confidence) & (x >= 0) & (x < W) & (y >= 0) & (y < H)
    shown = inside.copy()
    shown[inside] = ~hidden[y[inside], x[inside]]
    return int(inside.sum()), int(shown.sum())


#: BlazePose bones drawn to split a mask between people: face, arms, trunk, legs, feet
BONES = ((0, 11), (0, 12), (11, 12), (11, 13), (13, 15), (12, 14), (14, 16), (11, 23), (12, 24), (23, 24),
         (23, 25), (25, 27), (24, 26), (26, 28), (27, 29), (29, 31), (28, 30), (30, 32), (27, 31), (28, 32))


def split_masks(masks: list[np.ndarray], keypoints: list[np.ndarray], min_confidence: float = 0.5,
                reach: float = 0.1, step: int = 4) -> list[np.ndarray]:
    """Each person's mask (H, W) keeps only the pixels nearer its own skeleton (the bones
    between its keypoints with confidence >= ``min_confidence``) than any other person's, and
    within ``reach`` x its keypoints' height of it: BlazePose's segmentation is of every
    person in its crop, so where people overlap one person's mask covers the other.
    Distances on a grid of ``step`` pixels."""
    if not masks:
        return masks
    H, W = masks[0].shape
    h, w = (H + step - 1) // step, (W + step - 1) // step
    dist = []
    for kp in keypoints:
        canvas = np.full((h, w), 255, np.uint8)
        ok = kp[:, 2] >= min_confidence
        pts = np.round((kp[:, :2] + 0.5) / step - 0.5).astype(np.int64)
        for a, b in BONES:
            if ok[a] and ok[b]:
                cv2.line(canvas, (int(pts[a, 0]), int(pts[a, 1])), (int(pts[b, 0]), int(pts[b, 1])), 0, 1)
        for x, y in pts[ok]:
            cv2.circle(canvas, (int(x), int(y)), 1, 0, -1)
        d = cv2.distanceTransform(canvas, cv2.DIST_L2, 3)
        height = np.ptp(kp[ok, 1]) / step if ok.sum() >= 2 else 0.0
        dist.append(np.where(d <= max(reach * height, 2.0), d, np.inf))
    dist = np.stack(dist)
    nearest = np.where(np.isfinite(dist).any(axis=0), np.argmin(dist, axis=0), 255).astype(np.uint8)
    nearest = cv2.resize(nearest, (W, H), interpolation=cv2.INTER_NEAREST)
    return [m * (nearest == k) for k, m in enumerate(masks)]


PoseFn = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray] | None]


def mediapipe_pose(settings: DetectorSettings) -> tuple[PoseFn, Callable[[], None]]:
    """BlazePose in single-image mode (its person detector runs on every call) as a function
    rgb (h, w, 3) uint8 -> ((33, 3) keypoints in pixels, (h, w) mask) or None; and its closer."""
    mp_pose = _import_mediapipe()
    with contextlib.redirect_stderr(io.StringIO()):
        pose = mp_pose.Pose(static_image_mode=True, model_complexity=settings.model_complexity,
                            enable_segmentation=settings.segmentation,
                            min_detection_confidence=settings.min_detection_confidence)

    def run(rgb: np.ndarray):
        h, w = rgb.shape[:2]
        res = pose.process(np.ascontiguousarray(rgb))
        if res.pose_landmarks is None:
            return None
        kp = np.array([(p.x, p.y, p.visibility) for p in res.pose_landmarks.landmark], np.float64)
        kp[:, 0] = kp[:, 0] * w - 0.5
        kp[:, 1] = kp[:, 1] * h - 0.5
        kp[:, 2] = np.clip(kp[:, 2], 1e-3, 1.0)
        mask = (np.zeros((h, w), np.float32) if res.segmentation_mask is None
                else np.asarray(res.segmentation_mask, np.float32).reshape(h, w))
        return kp, mask

    return run, pose.close


@dataclass
class _Track:
    id: int
    keypoints: np.ndarray           # last seen (33, 3)
    mask: np.ndarray                # last seen (H, W)
    missed: int = 0


class PeopleDetector:
    """Several people in one view's frames, in order (see the module's docstring).

    pose: a function rgb -> (keypoints, mask) | None (default: BlazePose single-image mode);
    the tests give a stand-in. Ids start at 0 and are never reused within the view."""

    def __init__(self, settings: PeopleSettings | None = None, pose: PoseFn | None = None):
        self.settings = settings or PeopleSettings()
        self._close = None
        if pose is None:
            pose, self._close = mediapipe_pose(self.settings.detector)
        self.pose = pose
        self.tracks: list[_Track] = []
        self.frame = 0
        self._next_id = 0
        self.leftovers = 0              # search finds refused as leftover parts of people found

    # -- one call of the pose model, in full-image pixels --------------------------------------
    def _pose_in(self, rgb: np.ndarray, crop: tuple[int, int, int, int] | None):
        H, W = rgb.shape[:2]
        x0, y0, x1, y1 = crop if crop is not None else (0, 0, W, H)
        if x1 - x0 < 8 or y1 - y0 < 8:
            return None
        got = self.pose(np.ascontiguousarray(rgb[y0:y1, x0:x1]))
        if got is None:
            return None
        kp, m = got
        if (kp[:, 2] >= self.settings.min_confidence).sum() < self.settings.min_keypoints:
            return None
        kp = kp.copy()
        kp[:, 0] += x0
        kp[:, 1] += y0
        mask = np.zeros((H, W), np.float32)
        mask[y0:y1, x0:x1] = split_masks([m], [kp - np.array([x0, y0, 0])], self.settings.min_confidence)[0]
        return kp, mask

    def search(self, rgb: np.ndarray, masks: list[np.ndarray], known: list[np.ndarray], count: int
               ) -> list[tuple[np.ndarray, np.ndarray]]:
        """Up to ``count`` people not yet found: the pose model on the whole image with the
        masks of the people found so far (``masks`` with keypoints ``known``, and each new
        find) blacked out; a find on one of them (keypoints within ``same_distance``: the rest
        of a person its mask missed) has its box blacked out too and the search goes on. Only
        masks are hidden first, not boxes (a box would hide a person standing behind); when
        nothing more is found so, the found people's boxes are blacked out too and the search
        goes on (BlazePose returns only its best candidate, which may be a blurred body that
        its landmark model then rejects). A find with fewer than ``min_keypoints``, or less
        than ``min_shown`` of its confident keypoints, on pixels the search image shows is what
        is left of a person found (an arm outside its mask, the model completing a body over
        the hidden pixels): its box is hidden too and the search goes on; one with none shown
        is treated as nothing found (the found people's boxes hidden next, then the end)."""
        s = self.settings
        found = []
        masks, known, hidden = list(masks), list(known), []
        boxes_too = False
        for _ in range(count + len(known) + 2):
            if len(found) == count:
                break
            boxes = [keypoint_boxes(k, s.min_confidence) for k in known] if boxes_too else []
            got = self._pose_in(black_out(rgb, masks, hidden + boxes), None)
            if got is None:
                if boxes_too or not known:
                    break
                boxes_too = True        # the blurred bodies may still draw the detector: hide their boxes
                continue
            near = keypoint_distance(got[0][None], np.stack(known), s.min_confidence) if known else None
            if near is not None and near.min() < s.same_distance:
                hidden.append(keypoint_boxes(got[0], s.min_confidence))
                continue                # the rest of someone found already: hidden, search again
            if masks or hidden or boxes:
                gone = hidden_pixels(rgb.shape[:2], masks, hidden + boxes)
                confident, shown = shown_keypoints(got[0], gone, s.min_confidence)
                if shown < s.min_keypoints or shown < s.min_shown * confident:
                    self.leftovers += 1
                    if shown == 0:      # all made up over hidden pixels: the blurred bodies draw the model
                        if boxes_too:
                            break
                        boxes_too = True    # hide their boxes, as when nothing is found
                        continue
                    hidden.append(keypoint_boxes(got[0], s.min_confidence))
                    continue            # mostly made up over hidden pixels: leftover parts, hidden
            found.append(got)
            masks.append(got[1])
            known.append(got[0])
        return found

    def __call__(self, rgb: np.ndarray) -> list[Person]:
        s = self.settings
        H, W = rgb.shape[:2]
        if self.tracks and self.tracks[0].mask.shape != (H, W):
            raise ValueError(f"PeopleDetector: frame of {W}x{H} after frames of "
                             f"{self.tracks[0].mask.shape[1]}x{self.tracks[0].mask.shape[0]}: one view's "
                             "frames keep one size (one detector per view)")
        new: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        for t in self.tracks:                    # follow each person in a crop around its last keypoints
            box = keypoint_boxes(t.keypoints, s.min_confidence)
            grow = s.margin * (1 + 0.5 * t.missed)
            others = [o.mask * (t.mask < 0.5) for o in self.tracks if o is not t]
            got = self._pose_in(black_out(rgb, others, []), crop_box(box, grow, W, H))
            if got is not None:
                new[t.id] = got
        self._drop_duplicates(new)
        wanted = s.wanted - len(new)
        missing = any(t.id not in new for t in self.tracks)
        due = (not self.tracks or self.frame % s.search_every == 0 or missing
               or (s.people is not None and len(self.tracks) < s.people))
        if wanted > 0 and due:
            kept = list(new.values())
            finds = self.search(rgb, [m for _, m in kept], [k for k, _ in kept], wanted)
            for kp, mask in finds:
                self._attach(kp, mask, new)
        ids = sorted(new)
        split = split_masks([new[i][1] for i in ids], [new[i][0] for i in ids], s.min_confidence)
        new = {i: (new[i][0], m) for i, m in zip(ids, split, strict=True)}
        for t in self.tracks:
            if t.id in new:
                t.keypoints, t.mask = new[t.id]
                t.missed = 0
            else:
                t.missed += 1
        if s.people is None:                 # a fixed number: ids wait to be found again, never retired
            self.tracks = [t for t in self.tracks if t.missed <= s.lost_after]
        self.frame += 1
        return [Person(i, *new[i]) for i in ids]

    def _drop_duplicates(self, new: dict[int, tuple[np.ndarray, np.ndarray]]) -> None:
        """Two followed people on the same body (keypoints within ``same_distance``): keep
        the one whose keypoints moved less from its own previous ones (the other lost its
        person this frame)."""
        ids = sorted(new)
        if len(ids) < 2:
            return
        s = self.settings
        last = {t.id: t.keypoints for t in self.tracks}
        kps = np.stack([new[i][0] for i in ids])
        same = keypoint_distance(kps, kps, s.min_confidence)
        moved = {i: keypoint_distance(kps[[k]], last[i][None], s.min_confidence)[0, 0]
                 for k, i in enumerate(ids)}
        for a in range(len(ids)):
            for b in range(a + 1, len(ids)):
                ia, ib = ids[a], ids[b]
                if ia in new and ib in new and same[a, b] < s.same_distance:
                    del new[ib if moved[ia] <= moved[ib] else ia]

    def _attach(self, kp: np.ndarray, mask: np.ndarray, new: dict) -> None:
        """A search's find: a lost person back (its last box overlaps most; with a fixed number
        of people all taken, the lost one whose last box is nearest), or a new id."""
        s = self.settings
        box = keypoint_boxes(kp, s.min_confidence)[None]
        if new and keypoint_distance(kp[None], np.stack([k for k, _ in new.values()]),
                                     s.min_confidence).min() < s.same_distance:
            return
        lost = [t for t in self.tracks if t.id not in new]
        if lost:
            iou = box_iou(box, np.stack([keypoint_boxes(t.keypoints, s.min_confidence) for t in lost]))[0]
            k = int(np.argmax(iou))
            if iou[k] > s.new_iou:
                new[lost[k].id] = (kp, mask)
                return
            if s.people is not None and len(self.tracks) >= s.people:
                centre = lambda b: np.array([b[0] + b[2], b[1] + b[3]]) / 2      # noqa: E731
                far = [np.linalg.norm(centre(box[0]) - centre(keypoint_boxes(t.keypoints, s.min_confidence)))
                       for t in lost]
                new[lost[int(np.argmin(far))].id] = (kp, mask)
                return
        if len(self.tracks) >= s.wanted:
            return
        tid = self._next_id
        self._next_id += 1
        self.tracks.append(_Track(tid, kp, mask, missed=0))
        new[tid] = (kp, mask)

    def close(self) -> None:
        if self._close is not None:
            self._close()
            self._close = None

    def __enter__(self) -> PeopleDetector:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


__all__ = ["AUTO", "NUM_KEYPOINTS", "PeopleDetector", "PeopleSettings", "Person", "box_iou", "crop_box",
           "hidden_pixels", "keypoint_boxes", "keypoint_distance", "parse_people", "shown_keypoints",
           "split_masks"]
