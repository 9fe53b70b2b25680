"""Frame sources: video files and image-sequence folders, streamed one frame at a time.

:func:`open_source` looks at a path and returns a :class:`FrameSource` for one of these
layouts (checked in this order for a folder):

``video``
    A file that ``cv2.VideoCapture`` opens (``.avi .mp4 .mov .mkv`` ...).
``mot``
    A MOTChallenge sequence folder: ``seqinfo.ini`` (section ``[Sequence]`` with
    ``imDir``, ``imExt``, ``frameRate``, ``seqLength``) and the image folder ``img1/``;
    ``gt/gt.txt`` and ``det/det.txt`` when present. A folder with ``seqinfo.ini`` whose
    image folder is absent but which holds exactly one video file (the layout of
    ``PETS09-S2L1-video``) is streamed from that video, with the frame rate and
    annotations of the folder.
``otb``
    An OTB sequence folder: ``img/`` and ``groundtruth_rect.txt``.
``miltrack``
    The MILTrack release layout (``FaceOcc1``): ``imgs/``, ``<name>_gt.txt`` and an
    optional ``<name>_frames.txt``.
``images``
    A plain folder of images (``.jpg .jpeg .png .bmp .tif .tiff``), in natural sort order
    (``img2.png`` before ``img10.png``).

Every source yields ``(frame_number, image)`` pairs, ``frame_number`` 1-based in the
source's order and ``image`` a ``uint8`` BGR array of shape ``(H, W, 3)`` (greyscale
files are delivered as three equal channels). Frames are decoded one at a time and
never all held in memory.
"""

from __future__ import annotations

import configparser
import itertools
import logging
import math
from abc import ABC, abstractmethod
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from pgm.core.errors import InputError
from pgm.io.image_files import (  # noqa: F401 - IMAGE_EXTENSIONS, natural_key: re-exported
    IMAGE_EXTENSIONS,
    _list_images,
    _warn_numbering_gap,
    natural_key,
)
from pgm.io.prefetch import read_ahead
from pgm.io.track_files import format_numbers

__all__ = [
    "IMAGE_EXTENSIONS",
    "DEFAULT_FPS",
    "FrameSource",
    "ImageSequenceSource",
    "LiveSource",
    "IterableSource",
    "is_live",
    "VideoSource",
    "open_source",
    "natural_key",
    "write_image_sequence",
    "write_seqinfo",
]

DEFAULT_FPS: float = 25.0
"""Frame rate reported for image folders that do not declare one."""

_log = logging.getLogger(__name__)

MIN_FPS: float = 0.01
"""Lowest frame rate accepted from ``seqinfo.ini`` (one frame per 100 s)."""
MAX_FPS: float = 10000.0
"""Highest frame rate accepted from ``seqinfo.ini`` (a high-speed camera)."""


def _as_bgr(image: np.ndarray) -> np.ndarray:
    """Force an image to ``uint8`` BGR with three channels."""
    if image.dtype != np.uint8:
        if image.dtype == np.uint16:
            image = (image >> 8).astype(np.uint8)
        else:
            image = np.clip(image, 0, 255).astype(np.uint8)
    if image.ndim == 2:
        return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    if image.shape[2] == 1:
        return cv2.cvtColor(image[:, :, 0], cv2.COLOR_GRAY2BGR)
    if image.shape[2] == 4:
        return cv2.cvtColor(image, cv2.COLOR_BGRA2BGR)
    return image


def _check_range(start: int, stop: int | None, path: Path) -> tuple[int, int | None]:
    """Validate a 1-based ``[start, stop)`` frame range."""
    try:
        start_i = int(start)
        stop_i = None if stop is None else int(stop)
    except (TypeError, ValueError):
        raise InputError(f"frame range must be integers (got start={start!r}, stop={stop!r})"
                         f" for {path}") from None
    if start_i < 1:
        raise InputError(f"frame range start must be >= 1 (got {start_i}) for {path}")
    if stop_i is not None and stop_i < start_i:
        raise InputError(f"frame range stop ({stop_i}) is before start ({start_i}) for {path}")
    return start_i, stop_i


class FrameSource(ABC):
    """A sequence of frames, streamed.

    Attributes
    ----------
    name : str
        Sequence name (seqinfo ``name``, else the folder name or the video's file stem).
    path : Path
        The path that was opened.
    layout : str
        ``'video'``, ``'mot'``, ``'otb'``, ``'miltrack'`` or ``'images'``.
    fps : float
        Frame rate: seqinfo ``frameRate``, the video's ``CAP_PROP_FPS``, one given, else
        :data:`DEFAULT_FPS` (25).
    fps_declared : bool
        Whether ``fps`` was read or given (False where it is :data:`DEFAULT_FPS` for want
        of one: an OTB or MILTrack folder, images without ``seqinfo.ini``): a model whose
        constants are in seconds reads only a declared rate (:meth:`declare_fps`).
    gt_path : Path or None
        Default ground-truth file of the layout (``gt/gt.txt``,
        ``groundtruth_rect.txt``, ``*_gt.txt``), or None.
    gt_format : {'mot', 'otb', 'miltrack'} or None
        Format of ``gt_path``, as accepted by
        :func:`pgm.io.annotations.load_single_gt`.
    det_path : Path or None
        MOTChallenge public detections (``det/det.txt``), or None.

    Notes
    -----
    Iterating yields ``(frame_number, image)``; see :meth:`frames` for a sub-range.
    """

    name: str
    path: Path
    layout: str
    fps: float
    gt_path: Path | None
    gt_format: str | None
    det_path: Path | None

    def __init__(self, path: Path, *, name: str, layout: str, fps: float | None,
                 gt_path: Path | None = None, gt_format: str | None = None,
                 det_path: Path | None = None) -> None:
        self.path = path
        self.name = name
        self.layout = layout
        self.fps_declared = fps is not None
        self.fps = float(DEFAULT_FPS if fps is None else fps)
        self.gt_path = gt_path
        self.gt_format = gt_format if gt_path is not None else None
        self.det_path = det_path

    def declare_fps(self, fps: float) -> None:
        """Give the frame rate (e.g. from a dataset's documentation: UAV123@10fps's
        folders say nothing of their 10 frames/s)."""
        fps = float(fps)
        if not MIN_FPS <= fps <= MAX_FPS:
            raise InputError(f"frame rate {fps:g} is outside [{MIN_FPS:g}, {MAX_FPS:g}]")
        self.fps, self.fps_declared = fps, True

    @property
    @abstractmethod
    def size(self) -> tuple[int, int]:
        """``(width, height)`` of the frames, read from the first frame."""

    @abstractmethod
    def __len__(self) -> int:
        """Number of frames."""

    @abstractmethod
    def frames(self, start: int = 1, stop: int | None = None
               ) -> Iterator[tuple[int, np.ndarray]]:
        """Yield ``(frame_number, image)`` for ``start <= frame_number < stop``.

        Parameters
        ----------
        start : int
            First frame, 1-based.
        stop : int or None
            One past the last frame, like :func:`range` (``frames(1, 4)`` yields frames
            1, 2, 3); None for the end of the source.

        Yields
        ------
        frame_number : int
            1-based position in the source's order.
        image : ndarray, shape (H, W, 3), uint8
            BGR image.
        """

    def __iter__(self) -> Iterator[tuple[int, np.ndarray]]:
        return self.frames()

    def __repr__(self) -> str:
        n = self._known_length()
        return (f"{type(self).__name__}(name={self.name!r}, layout={self.layout!r}, "
                f"frames={'?' if n is None else n}, fps={self.fps:g}, "
                f"path={str(self.path)!r})")

    def _known_length(self) -> int | None:
        """The frame count if it is known without decoding, else None."""
        return len(self)


class ImageSequenceSource(FrameSource):
    """Frames stored as one image file per frame (MOT, OTB, MILTrack or a plain folder).

    Frame ``k`` (1-based) is ``files[k - 1]``. Files are decoded only when their frame is
    reached, so :meth:`frames` with a sub-range never reads skipped files.

    Notes
    -----
    OTB: line *i* of ``groundtruth_rect.txt`` pairs with the *i*-th image; a few OTB-100
    sequences (e.g. ``David``, ``Tiger1``, ``BlurCar1``) start their benchmark range
    after the first image, an offset this reader does not apply.

    MILTrack (``FaceOcc1``): the images ``imgs/img00000.png ...`` are frames 1, 2, ...
    in sorted order, and line *k* (0-based) of ``*_gt.txt`` pairs with ``img{k:05d}``,
    i.e. frame *k + 1*. The release's ``*_frames.txt`` (``2,887`` for FaceOcc1) would
    shift that pairing by its first number under MILTrack's own loader; it is ignored
    here, following ``phecy/ACCV2012_Code`` (see the data's ``SOURCE.md``: the
    alignment is uncertain by up to two frames, which hardly moves the metrics).
    MILTrack boxes are 0-based (C++/OpenCV origin), unlike OTB/MOT.
    """

    def __init__(self, path: Path, files: list[Path], **kwargs) -> None:
        super().__init__(path, **kwargs)
        if not files:
            raise InputError(f"no image files (.jpg .png .bmp .tif) in folder {path}")
        self.files: list[Path] = files
        self._size: tuple[int, int] | None = None
        _warn_numbering_gap(path, files)

    def __len__(self) -> int:
        return len(self.files)

    @property
    def size(self) -> tuple[int, int]:
        """``(width, height)`` from the first image's header (not a full decode)."""
        if self._size is None:
            first = self.files[0]
            try:
                from PIL import Image  # header-only read; Pillow comes with matplotlib
            except ImportError:  # pragma: no cover - Pillow is a matplotlib dependency
                h, w = _read_image(first).shape[:2]
                self._size = (int(w), int(h))
            else:
                try:
                    with Image.open(first) as im:
                        self._size = (int(im.size[0]), int(im.size[1]))
                except Exception as exc:  # PIL raises several types for corrupt headers
                    raise InputError(f"cannot read image header of {first}: "
                                     f"{_one_line(exc)}") from None
        return self._size

    def frames(self, start: int = 1, stop: int | None = None
               ) -> Iterator[tuple[int, np.ndarray]]:
        """As :meth:`FrameSource.frames`; the next :data:`PREFETCH` images are decoded by
        a thread while the caller works on this one (decoding releases the GIL), and a
        file's error is raised when its frame is reached, as without it."""
        start, stop = _check_range(start, stop, self.path)
        return read_ahead(self._decode(start, stop), PREFETCH)

    def _decode(self, start: int, stop: int | None) -> Iterator[tuple[int, np.ndarray]]:
        end = len(self.files) if stop is None else min(stop - 1, len(self.files))
        first: tuple[int, int] | None = None
        for number in range(start, end + 1):
            image = _read_image(self.files[number - 1])
            first = _check_same_size(first, image,
                                     f"image {self.files[number - 1]} (frame {number})")
            yield number, image


#: frames a source decodes ahead of the one being used (:func:`pgm.io.prefetch.read_ahead`)
PREFETCH = 2


def _check_same_size(first: tuple[int, int] | None, image: np.ndarray,
                     what: str) -> tuple[int, int]:
    """The ``(width, height)`` every frame must have (the first frame's); an
    :class:`InputError` for a frame of another size."""
    size = (int(image.shape[1]), int(image.shape[0]))
    if first is not None and size != first:
        raise InputError(f"{what} is {size[0]}x{size[1]} but the sequence's frames are "
                         f"{first[0]}x{first[1]}; every frame must have the same size")
    return size if first is None else first


def _one_line(exc: BaseException) -> str:
    """An exception's message squashed to one line."""
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


def _read_image(path: Path) -> np.ndarray:
    """Decode one image file to ``uint8`` BGR, raising :class:`InputError` if corrupt."""
    try:
        buf = np.fromfile(path, dtype=np.uint8)
    except OSError as exc:
        raise InputError(f"cannot read image file {path}: {_one_line(exc)}") from None
    if buf.size == 0:
        raise InputError(f"empty image file {path}")
    try:
        image = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    except cv2.error as exc:
        raise InputError(f"corrupt image file {path}: {_one_line(exc)}") from None
    if image is None:
        raise InputError(f"corrupt or unsupported image file {path}")
    return _as_bgr(image)


class VideoSource(FrameSource):
    """Frames decoded from a video file with ``cv2.VideoCapture``.

    The file is opened, and its first frame decoded, when the source is created, so an
    unreadable or corrupt video fails early. Each iteration opens a fresh capture.

    Notes
    -----
    ``len()`` is the container's ``CAP_PROP_FRAME_COUNT`` (counted by decoding when the
    container does not say). ``fps`` is the container's ``CAP_PROP_FPS`` unless the
    video was opened through a MOT folder with ``seqinfo.ini``: e.g. PETS09
    ``vtest.avi`` says 10 fps while MOT15 uses 7. A video that sits in a MOT sequence
    folder (next to ``seqinfo.ini``) takes ``gt/gt.txt`` and ``det/det.txt`` from it;
    video frame index *i* (0-based) is frame number *i + 1*.
    """

    def __init__(self, path: Path, *, video_path: Path | None = None,
                 fps: float | None = None, **kwargs) -> None:
        self.video_path: Path = path if video_path is None else video_path
        cap = self._open()
        try:
            ok, first = cap.read()
            if not ok or first is None:
                raise InputError(f"cannot decode the first frame of video {self.video_path}"
                                 " (corrupt or unsupported codec)")
            container_fps = float(cap.get(cv2.CAP_PROP_FPS) or 0.0)
            count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
        finally:
            cap.release()
        if fps is None:
            fps = container_fps if MIN_FPS <= container_fps <= MAX_FPS else None
        super().__init__(path, fps=fps, **kwargs)
        first = _as_bgr(first)
        self._size: tuple[int, int] = (int(first.shape[1]), int(first.shape[0]))
        self._count: int | None = count if count > 0 else None

    def _open(self) -> cv2.VideoCapture:
        cap = cv2.VideoCapture(str(self.video_path))
        if not cap.isOpened():
            cap.release()
            raise InputError(f"cannot open video file {self.video_path}"
                             " (not a video, or an unsupported/corrupt container)")
        return cap

    def _known_length(self) -> int | None:
        return self._count

    @property
    def size(self) -> tuple[int, int]:
        """``(width, height)`` of the first decoded frame."""
        return self._size

    def __len__(self) -> int:
        if self._count is None:
            cap = self._open()
            n = 0
            try:
                while cap.grab():
                    n += 1
            finally:
                cap.release()
            self._count = n
        return self._count

    def frames(self, start: int = 1, stop: int | None = None
               ) -> Iterator[tuple[int, np.ndarray]]:
        """As :meth:`FrameSource.frames`; the frames are decoded by a thread of their own
        up to :data:`PREFETCH` ahead of the one being used (decoding releases the GIL), and
        a decoding error is raised when its frame is reached, as without it."""
        start, stop = _check_range(start, stop, self.path)
        return read_ahead(self._decode(start, stop), PREFETCH)

    def _decode(self, start: int, stop: int | None) -> Iterator[tuple[int, np.ndarray]]:
        cap = self._open()
        first: tuple[int, int] | None = None
        try:
            k = 1
            while k < start:  # grab() skips without converting the frame
                if not cap.grab():
                    return
                k += 1
            while stop is None or k < stop:
                ok, image = cap.read()
                if not ok or image is None:
                    expected = self._count
                    if expected is not None and k <= expected:
                        _log.warning("video %s ended after %d frames; the container says %d",
                                     self.video_path, k - 1, expected)
                    return
                image = _as_bgr(image)
                first = _check_same_size(first, image, f"frame {k} of video {self.video_path}")
                yield k, image
                k += 1
        finally:
            cap.release()


def _read_seqinfo(ini: Path) -> dict[str, str]:
    """The ``[Sequence]`` section of a MOTChallenge ``seqinfo.ini``, keys lower-cased."""
    parser = configparser.ConfigParser(interpolation=None)
    try:
        text = ini.read_text(encoding="utf-8-sig", errors="replace")
        parser.read_string(text, source=str(ini))
    except (configparser.Error, OSError) as exc:
        raise InputError(f"malformed seqinfo.ini {ini}: {_one_line(exc)}") from None
    section = next((s for s in parser.sections() if s.lower() == "sequence"), None)
    if section is None:
        raise InputError(f"malformed seqinfo.ini {ini}: no [Sequence] section")
    return {k.lower(): v.strip() for k, v in parser.items(section)}


def _seqinfo_number(info: dict[str, str], key: str, ini: Path, *, integer: bool) -> float | None:
    raw = info.get(key.lower())
    if raw is None or raw == "":
        return None
    try:
        value = float(raw)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value <= 0 or (integer and value != int(value)):
        kind = "a positive integer" if integer else "a positive number"
        raise InputError(f"malformed seqinfo.ini {ini}: {key}={raw!r} is not {kind}")
    if integer and value > 1e9:
        raise InputError(f"malformed seqinfo.ini {ini}: {key}={raw!r} is implausibly large")
    if key == "frameRate" and not MIN_FPS <= value <= MAX_FPS:
        raise InputError(f"malformed seqinfo.ini {ini}: frameRate={raw!r} is outside "
                         f"[{MIN_FPS:g}, {MAX_FPS:g}] frames per second")
    return value


def _video_files(folder: Path) -> list[Path]:
    skip = IMAGE_EXTENSIONS | {".txt", ".ini", ".md", ".json", ".csv", ".xml", ".yaml", ".yml"}
    return sorted(p for p in folder.iterdir()
                  if p.is_file() and p.suffix.lower() not in skip and p.suffix)


def _open_mot(folder: Path) -> FrameSource:
    ini = folder / "seqinfo.ini"
    info: dict[str, str] = _read_seqinfo(ini) if ini.is_file() else {}
    name = info.get("name") or folder.name
    im_dir = info.get("imdir") or "img1"
    im_ext = info.get("imext") or ".jpg"
    if not im_ext.startswith("."):
        im_ext = "." + im_ext
    fps = _seqinfo_number(info, "frameRate", ini, integer=False) or None
    seq_length = _seqinfo_number(info, "seqLength", ini, integer=True)
    gt = folder / "gt" / "gt.txt"
    det = folder / "det" / "det.txt"
    common = dict(name=name, layout="mot", gt_path=gt if gt.is_file() else None,
                  gt_format="mot", det_path=det if det.is_file() else None)
    img_folder = folder / im_dir
    if not img_folder.is_dir():
        videos = _video_files(folder)
        if len(videos) == 1:
            return VideoSource(folder, video_path=videos[0], fps=fps, **common)
        raise InputError(f"MOT sequence folder {folder} has no image folder {im_dir}/")
    files = _list_images(img_folder, im_ext)
    if seq_length is not None and int(seq_length) != len(files):
        _log.warning("%s says seqLength=%d but %s has %d %s images; using %d", ini,
                     int(seq_length), img_folder, len(files), im_ext,
                     min(len(files), int(seq_length)))
        files = files[: int(seq_length)]
    return ImageSequenceSource(folder, files, fps=fps, **common)


def _open_folder(folder: Path) -> FrameSource:
    if (folder / "seqinfo.ini").is_file() or (folder / "img1").is_dir():
        return _open_mot(folder)
    if (folder / "img").is_dir():
        gt = folder / "groundtruth_rect.txt"
        if not gt.is_file():
            alts = sorted(folder.glob("groundtruth_rect*.txt"), key=lambda p: natural_key(p.name))
            gt = alts[0] if alts else None
        return ImageSequenceSource(folder, _list_images(folder / "img"), name=folder.name,
                                   layout="otb", fps=None, gt_path=gt,
                                   gt_format="otb")
    if (folder / "imgs").is_dir():
        gts = sorted(p for p in folder.glob("*_gt.txt") if p.is_file())
        return ImageSequenceSource(folder, _list_images(folder / "imgs"), name=folder.name,
                                   layout="miltrack", fps=None,
                                   gt_path=gts[0] if gts else None, gt_format="miltrack")
    return ImageSequenceSource(folder, _list_images(folder), name=folder.name, layout="images",
                               fps=None)


class IterableSource(FrameSource):
    """Frames from any iterable of BGR images or of ``(frame_number, image)`` pairs (e.g.
    a generator reading a camera SDK), read once, as they come.

    Its length is unknown (``len()`` is 0 and :meth:`_known_length` None) and
    :meth:`frames` can be iterated once and never seeks. The first frame is read when
    the source is created (for its size).
    """

    def __init__(self, frames, *, fps: float | None = None, name: str = "frames",
                 layout: str = "iterable", path: Path | None = None) -> None:
        it = iter(frames)
        try:
            first = next(it)
        except StopIteration:
            raise InputError("the frame iterable is empty") from None
        image = np.asarray(first[1] if isinstance(first, tuple) else first)
        if image.ndim not in (2, 3) or image.size == 0:
            raise InputError(f"frames must be images (H, W[, 3]), got shape {image.shape}")
        super().__init__(Path(name) if path is None else path, name=name, layout=layout,
                         fps=None if fps is None else float(fps))
        self._frames = itertools.chain((first,), it)
        self._size = (int(image.shape[1]), int(image.shape[0]))

    @property
    def size(self) -> tuple[int, int]:
        """``(width, height)`` of the first frame."""
        return self._size

    def __len__(self) -> int:
        return 0

    def _known_length(self) -> int | None:
        return None

    def frames(self, start: int = 1, stop: int | None = None
               ) -> Iterator[tuple[int, np.ndarray]]:
        start, stop = _check_range(start, stop, self.path)
        if self._frames is None:
            raise InputError(f"{self.name} was already read: it is read once, as it comes")
        frames, self._frames = self._frames, None
        for k, item in enumerate(frames, start=1):
            number, image = item if isinstance(item, tuple) else (k, item)
            if stop is not None and number >= stop:
                return
            if number >= start:
                yield int(number), _as_bgr(np.asarray(image))


class LiveSource(IterableSource):
    """Frames from a camera (an integer index, e.g. ``0``) or a stream URL (``rtsp://``,
    ``http(s)://``, ``udp://``, ``file://``), read with ``cv2.VideoCapture``: an
    :class:`IterableSource` over the capture, so read once, as it comes; a frame that
    does not arrive ends the stream. The camera or stream is opened, and its first frame
    read, when the source is created, so a missing camera fails early.
    """

    def __init__(self, spec: str, *, fps: float | None = None) -> None:
        self.spec = str(spec)
        target: int | str = int(self.spec) if self.spec.isdigit() else self.spec
        what = f"camera {self.spec}" if isinstance(target, int) else f"stream {self.spec}"
        cap = cv2.VideoCapture(target)
        if not cap.isOpened():
            cap.release()
            raise InputError(f"cannot open {what} (no such device, or the stream cannot be "
                             f"reached)")
        rate = float(cap.get(cv2.CAP_PROP_FPS) or 0.0)
        if fps is None:
            fps = rate if MIN_FPS <= rate <= MAX_FPS else None

        def read():
            try:
                while True:
                    ok, image = cap.read()
                    if not ok or image is None:
                        return
                    yield image
            finally:
                cap.release()

        try:
            super().__init__(read(), fps=fps, name=what.replace(" ", "-"), layout="live",
                             path=Path(self.spec))
        except InputError:
            raise InputError(f"{what} opened but gave no frame") from None


#: what ``open_source`` treats as a live source rather than a path
LIVE_PREFIXES = ("rtsp://", "rtmp://", "http://", "https://", "udp://", "tcp://", "file://")


def is_live(spec: str | Path) -> bool:
    """Whether ``spec`` names a camera index (``"0"``) or a stream URL."""
    text = str(spec)
    return text.isdigit() or text.lower().startswith(LIVE_PREFIXES)


def open_source(path: str | Path) -> FrameSource:
    """Open a video file or an image-sequence folder as a :class:`FrameSource`.

    Parameters
    ----------
    path : str or Path
        A video file, a MOTChallenge / OTB / MILTrack sequence folder, or a folder of
        images (see the module docstring for how the layout is detected); or a camera
        index (``"0"``) or stream URL (``rtsp://…``): a :class:`LiveSource`.

    Returns
    -------
    FrameSource
        :class:`VideoSource` or :class:`ImageSequenceSource`.

    Raises
    ------
    InputError
        The path does not exist; a folder holds no images; a video cannot be opened or
        its first frame cannot be decoded; ``seqinfo.ini`` is malformed; the path is a
        named pipe or a socket (FFmpeg would wait on it for ever).
        A corrupt image file is reported when iteration reaches it.
    """
    if isinstance(path, str) and is_live(path) and not Path(path).exists():
        return LiveSource(path)
    p = Path(path).expanduser()
    if not p.exists():
        raise InputError(f"no such file or folder: {p}")
    if p.is_dir():
        return _open_folder(p)
    if p.is_fifo() or p.is_socket():
        # FFmpeg would block in open() on a pipe with no writer, in native code where
        # neither SIGINT nor SIGTERM reaches the run: refused before it is opened
        kind = "a named pipe (FIFO)" if p.is_fifo() else "a socket"
        raise InputError(f"{p} is {kind}, not a video file: give a file, an image folder, "
                         f"a camera index or a stream URL (e.g. udp://, tcp://)")
    if p.suffix.lower() in IMAGE_EXTENSIONS:
        raise InputError(f"{p} is a single image; pass the folder that holds the sequence")
    gt = p.parent / "gt" / "gt.txt"
    det = p.parent / "det" / "det.txt"
    in_mot = (p.parent / "seqinfo.ini").is_file()
    return VideoSource(p, name=p.stem, layout="video",
                       gt_path=gt if in_mot and gt.is_file() else None, gt_format="mot",
                       det_path=det if in_mot and det.is_file() else None)


# -- writing --------------------------------------------------------------------------
def write_image_sequence(folder: str | Path, frames, pattern: str = "{:06d}.png",
                         start: int = 1) -> Path:
    """Write BGR ``frames`` as numbered images ``folder/pattern.format(k)`` from ``start``
    (PNG at fast compression). Returns the folder."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for k, img in enumerate(frames, start=start):
        path = folder / pattern.format(k)
        if not cv2.imwrite(str(path), img, [cv2.IMWRITE_PNG_COMPRESSION, 1]):
            raise InputError(f"could not write image {path}")
    return folder


def write_seqinfo(folder: str | Path, *, name: str, fps: float, length: int, width: int,
                  height: int, im_dir: str = "img1", im_ext: str = ".png") -> Path:
    """Write a MOTChallenge ``seqinfo.ini`` (what :func:`open_source` reads back)."""
    path = Path(folder) / "seqinfo.ini"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("[Sequence]\n"
                    f"name={name}\nimDir={im_dir}\nframeRate={format_numbers([fps], 6)[0]}\n"
                    f"seqLength={int(length)}\nimWidth={int(width)}\nimHeight={int(height)}\n"
                    f"imExt={im_ext}\n")
    return path
