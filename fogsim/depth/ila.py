"""ILA — the iterative learning approach to depth completion (Chaar et al.), made measurable.

A U-Net maps RGB (optionally + the sparse disparity and its validity mask) to disparity.
Round r trains on targets whose holes are the stereo holes (round 0) or were filled with the
previous round's predictions; after each round the model predicts every training image and
the holes of the targets are filled with it; a checkpoint is saved per round.

Differences from the reference (Improve-depth-images): the loss is masked to valid target
pixels (the reference regresses holes to 0 — ``loss_on="all"`` keeps that for comparison),
width is configurable (``width=64`` is the reference's 31 M-parameter 64-128-256-512 net;
the default 16 has ~2 M and trains on a CPU), 16-bit disparity is read exactly, and the
output is resolution-independent.

Units: the network predicts ``d / W`` — disparity in pixels over image width — so one model
serves any resolution; depth in metres is ``baseline · (fx / W) / (d / W)`` with the
baseline and fx/W of the stereo camera it was trained on (stored in the checkpoint). For
another camera (e.g. Waymo's) that is right when its fx/W (field of view) matches.
torch is an optional extra: ``pip install -e ".[ila]"``.

Checkpoints hold tensors and plain data only (format :data:`CHECKPOINT_FORMAT`, see
:func:`save_checkpoint`) and are read with ``torch.load(weights_only=True)``: a checkpoint
from elsewhere can never run code, and every problem with one is a one-line
:class:`~fogsim.errors.InputError` naming it.
"""
from __future__ import annotations

import math
import zipfile
from dataclasses import asdict, dataclass, field, fields
from functools import lru_cache
from pathlib import Path
from typing import ClassVar

import numpy as np

from fogsim._version import __version__
from fogsim.camera import depth_to_disparity, disparity_to_depth
from fogsim.colour import full_scale
from fogsim.errors import InputError
from fogsim.io.atomic import atomic_path
from fogsim.io.images import read_image
from fogsim.readers.cityscapes import cityscapes_samples
from fogsim.readers.cityscapes_files import read_cityscapes_disparity


def _torch():
    from fogsim.deps import require

    return require("torch", "ila")  # a MissingDependency (exit 2) naming the extra


#: the pixels the loss is computed on (``loss_on``, ``--loss-on``): valid targets only, or all (holes → 0)
LOSS_ON = ("valid", "all")
#: the loss (``loss``, ``--loss``): MSE of d/W (the reference) or log-L1, |log d − log d*| (relative)
LOSSES = ("mse", "log_l1")


@dataclass(frozen=True)
class ILAConfig:
    """The ILA training configuration; ``fogsim ila train`` / ``bench ila`` flags of the same
    names (``--loss-on``, ``--loss``, ``--epochs`` …) set it, with these defaults. Checkpoints
    store it field by field."""

    width: int = 16             # channels of the first U-Net level (reference: 64)
    size: tuple[int, int] = (256, 128)  # training resolution W×H (reference: 480×320)
    use_sparse: bool = False    # also feed the sparse disparity and its validity mask
    sparse_drop: float = 0.3    # share of the sparse input hidden (in blobs) per training batch
    loss_on: str = "valid"      # one of LOSS_ON: "valid" (masked) or "all" (the reference: holes → 0)
    loss: str = "mse"           # one of LOSSES: "mse" of d/W (the reference) or "log_l1" (relative)
    rounds: int = 2
    epochs: int = 40
    batch: int = 4
    lr: float = 1e-3
    seed: int = 0

    #: bounds on what becomes memory: the training set is held at ``size`` (N × 5 channels × W × H
    #: float32), the U-Net's parameters grow with ``width`` squared (64: the reference's 31 M)
    MAX_PIXELS: ClassVar[int] = 2048 * 2048
    MAX_WIDTH: ClassVar[int] = 256

    def __post_init__(self):
        if len(self.size) != 2 or any(v < 16 or v % 16 for v in self.size):
            raise ValueError(f"ILA size must be positive multiples of 16 (four 2× poolings), got {self.size}")
        if self.size[0] * self.size[1] > self.MAX_PIXELS:
            raise ValueError(f"ILA size {self.size[0]}x{self.size[1]} is above {self.MAX_PIXELS / 2**20:g} MP "
                             "(the training set is held in memory at this size; the reference trains at 480x320)")
        for name in ("width", "rounds", "epochs", "batch"):
            if getattr(self, name) < 1:
                raise ValueError(f"ILA {name} must be ≥ 1, got {getattr(self, name)}")
        if self.width > self.MAX_WIDTH:
            raise ValueError(f"ILA width must be ≤ {self.MAX_WIDTH} (64 = the reference's 31 M parameters; they "
                             f"grow with its square), got {self.width}")
        if not 0 <= self.sparse_drop < 1:
            raise ValueError(f"sparse_drop must be in [0, 1), got {self.sparse_drop}")
        if not self.lr > 0:
            raise ValueError(f"lr must be > 0, got {self.lr}")
        if self.loss_on not in LOSS_ON:
            raise ValueError(f"loss_on must be 'valid' or 'all', got {self.loss_on!r}")
        if self.loss not in LOSSES:
            raise ValueError(f"loss must be 'mse' or 'log_l1', got {self.loss!r}")


@dataclass
class StereoSet:
    """Images and normalised disparity targets (d/W, 0 = hole) at the training size."""

    rgb: np.ndarray                # N×3×H×W float32 in [0, 1]
    target: np.ndarray             # N×1×H×W float32, d/W
    original_valid: np.ndarray     # N×1×H×W bool: valid in the stereo input
    keys: list[str] = field(default_factory=list)
    camera: dict = field(default_factory=dict)  # baseline_m, fx_over_w


def _unit_rgb(rgb: np.ndarray) -> np.ndarray:
    """An RGB image of any supported dtype (uint8, uint16, float) as float32 in [0, 1]."""
    return rgb.astype(np.float32) / np.float32(full_scale(rgb.dtype))


def load_stereo_set(root: str | Path, split: str, size: tuple[int, int]) -> StereoSet:
    """A Cityscapes-layout split (real Cityscapes or ``render_batch.py --stereo``) at ``size``."""
    import cv2

    rgbs, targets, keys, cams = [], [], [], []
    for s in cityscapes_samples(root, split):
        img = read_image(s.source)
        disparity, cam = read_cityscapes_disparity(s.depth.path, s.depth.camera_path)
        width = cam.intrinsics.width  # the disparity map's
        d = disparity / width  # d/W
        # nearest keeps holes holes; the value d/W is resolution-independent
        targets.append(cv2.resize(d, size, interpolation=cv2.INTER_NEAREST)[None])
        rgbs.append(_unit_rgb(cv2.resize(img, size, interpolation=cv2.INTER_AREA)).transpose(2, 0, 1))
        keys.append(s.key)
        cams.append((cam.baseline, cam.intrinsics.fx / width))
    target = np.stack(targets).astype(np.float32)
    return StereoSet(np.stack(rgbs).astype(np.float32), target, target > 0, keys,
                     {"baseline_m": float(np.median([c[0] for c in cams])),
                      "fx_over_w": float(np.median([c[1] for c in cams]))})


def build_unet(config: ILAConfig):
    """U-Net with levels (w, 2w, 4w, 8w) and a 16w bottleneck; softplus output (d/W ≥ 0)."""
    torch = _torch()
    nn = torch.nn

    def block(i, o):
        return nn.Sequential(nn.Conv2d(i, o, 3, padding=1), nn.BatchNorm2d(o), nn.ReLU(inplace=True),
                             nn.Conv2d(o, o, 3, padding=1), nn.BatchNorm2d(o), nn.ReLU(inplace=True))

    class UNet(nn.Module):
        def __init__(self, cin: int, w: int):
            super().__init__()
            chans = [w, 2 * w, 4 * w, 8 * w]
            self.down = nn.ModuleList()
            for c in chans:
                self.down.append(block(cin, c))
                cin = c
            self.bottom = block(chans[-1], 16 * w)
            self.up = nn.ModuleList(nn.ConvTranspose2d(2 * c, c, 2, stride=2) for c in reversed(chans))
            self.dec = nn.ModuleList(block(2 * c, c) for c in reversed(chans))
            self.head = nn.Conv2d(w, 1, 1)

        def forward(self, x):
            skips = []
            for blk in self.down:
                x = blk(x)
                skips.append(x)
                x = nn.functional.max_pool2d(x, 2)
            x = self.bottom(x)
            for up, dec, skip in zip(self.up, self.dec, reversed(skips)):
                x = dec(torch.cat([up(x), skip], 1))
            return nn.functional.softplus(self.head(x)) * 0.01  # d/W is O(0.01)

    return UNet(5 if config.use_sparse else 3, config.width)


def masked_loss(pred, target, valid, loss_on: str = "valid", kind: str = "mse"):
    """Error of d/W averaged over valid target pixels (``loss_on="all"``: over every pixel).

    ``mse``: squared error of d/W, as the reference. ``log_l1``: |log d − log d*|, a relative
    error like AbsRel (valid pixels only: a hole has no log).
    """
    torch = _torch()
    if kind == "log_l1":
        err = torch.abs(torch.log(pred.clamp(min=1e-6)) - torch.log(target.clamp(min=1e-6)))
    else:
        err = (pred - target) ** 2
    if loss_on == "all" and kind == "mse":
        return torch.mean(err)
    n = valid.sum()
    return torch.sum(err * valid) / torch.clamp(n, min=1)


def device():
    """CUDA when present, else CPU."""
    torch = _torch()
    return torch.device("cuda" if torch.cuda.is_available() else "cpu")


def _inputs(torch, data: StereoSet, idx, config: ILAConfig, drop: float = 0.0):
    """RGB, plus (``use_sparse``) the *stereo* disparity — never the filled targets, which have
    no holes and would teach the net to copy its input. ``drop`` hides that share of it in
    8×8-pixel blobs during training, so the net learns to fill holes from context."""
    x = torch.from_numpy(data.rgb[idx])
    if config.use_sparse:
        t = torch.from_numpy(data.target[idx])
        if drop > 0:
            b, _, h, w = t.shape
            keep = (torch.rand(b, 1, h // 8, w // 8) >= drop).float()
            t = t * torch.nn.functional.interpolate(keep, size=(h, w), mode="nearest")
        x = _with_sparse(torch, x, t)
    return x.to(device())


def _with_sparse(torch, x, t):
    """RGB batch + the sparse d/W (scaled to O(1)) and its validity mask: 5 input channels."""
    return torch.cat([x, t * 100.0, (t > 0).float()], 1)


def fill_targets(target: np.ndarray, prediction: np.ndarray) -> np.ndarray:
    """The ILA step: holes (0) of the targets take the prediction; valid pixels are kept."""
    return np.where(target > 0, target, prediction).astype(np.float32)


def predict(model, data: StereoSet, config: ILAConfig, batch: int = 8) -> np.ndarray:
    torch = _torch()
    model.eval()
    out = []
    with torch.no_grad():
        for i in range(0, len(data.rgb), batch):
            idx = np.arange(i, min(i + batch, len(data.rgb)))
            out.append(model(_inputs(torch, data, idx, config)).cpu().numpy())
    return np.concatenate(out)


def train_rounds(data: StereoSet, config: ILAConfig, out: str | Path, progress: bool = True) -> list[dict]:
    """Train ``config.rounds`` ILA rounds; checkpoint ``out/round_<r>.pt`` each; returns the log."""
    from tqdm import tqdm

    torch = _torch()
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    target, log = data.target.copy(), []
    for r in range(config.rounds):
        model = build_unet(config).to(device())
        opt = torch.optim.Adam(model.parameters(), lr=config.lr)
        n = len(data.rgb)
        bar = tqdm(range(config.epochs), desc=f"ILA round {r}", disable=not progress, unit="epoch")
        for _ in bar:
            model.train()
            losses, order = [], rng.permutation(n)
            for i in range(0, n, config.batch):
                idx = order[i:i + config.batch]
                t = torch.from_numpy(target[idx]).to(device())
                loss = masked_loss(model(_inputs(torch, data, idx, config, config.sparse_drop)), t, (t > 0).float(),
                                   config.loss_on, config.loss)
                opt.zero_grad()
                loss.backward()
                opt.step()
                losses.append(float(loss.detach()))
            bar.set_postfix(loss=f"{np.mean(losses):.3g}")
        pred = predict(model, data, config)
        filled = fill_targets(target, pred)
        entry = {"round": r, "loss": float(np.mean(losses)), "holes_before": float(np.mean(target == 0)),
                 "holes_after": float(np.mean(filled == 0)), "checkpoint": str(out / f"round_{r}.pt")}
        save_checkpoint(out / f"round_{r}.pt", model, config, data.camera, r)
        target = filled
        log.append(entry)
    return log


#: The checkpoint format :func:`save_checkpoint` writes and :func:`load_model` reads. fogsim
#: 0.1 wrote format 1 (the same keys without a format number, read with full unpickling).
CHECKPOINT_FORMAT = 2
FORMAT_KEY = "fogsim_ila_format"
_OUTPUT = "disparity / image width"


def save_checkpoint(path: str | Path, model, config: ILAConfig, camera: dict, round_: int) -> None:
    """Write a round's checkpoint atomically: tensors and plain data only.

    ``{FORMAT_KEY: 2, "fogsim": version, "config": ILAConfig as a dict (size a list),
    "camera": {"baseline_m", "fx_over_w"}, "round": r, "output": "disparity / image width",
    "state_dict": {name: tensor}}`` — all of it loadable with ``torch.load(weights_only=True)``.
    """
    torch = _torch()
    ck = {FORMAT_KEY: CHECKPOINT_FORMAT, "fogsim": __version__,
          "config": {**asdict(config), "size": list(config.size)},
          "camera": {"baseline_m": float(camera["baseline_m"]), "fx_over_w": float(camera["fx_over_w"])},
          "round": int(round_), "output": _OUTPUT,
          "state_dict": {k: v.detach().cpu() for k, v in model.state_dict().items()}}
    with atomic_path(path) as tmp:
        torch.save(ck, tmp)


def _first_line(exc: BaseException, limit: int = 160) -> str:
    """An exception's message on one line: its first line (with the next, when that one only
    introduces a list), cut to ``limit`` characters."""
    lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip()]
    text = " ".join(lines[:2]) if len(lines) > 1 and lines[0].endswith(":") else (lines[0] if lines else "")
    text = text or type(exc).__name__
    return text if len(text) <= limit else text[:limit - 1] + "…"


def read_checkpoint(checkpoint: str | Path) -> dict:
    """The checked contents of an ILA checkpoint; any problem is an :class:`InputError` naming it.

    Only a ``torch.save`` zip archive is opened, and only with ``weights_only=True``, so a
    crafted file cannot run code (:func:`_load_archive`); then the format number
    (:func:`_checkpoint_format`), the config, the camera and the weights' names and types are checked.
    """
    path = Path(checkpoint)
    ck = _load_archive(path)
    _checkpoint_format(ck, path)
    missing = [k for k in ("config", "camera", "round", "state_dict") if k not in ck]
    if missing:
        raise InputError(path, f"ILA checkpoint lacks {', '.join(map(repr, missing))}")
    ck["config"] = _config_from_dict(ck["config"], path)
    ck["camera"] = _camera_from_dict(ck["camera"], path)
    r = ck["round"]
    if not isinstance(r, int) or isinstance(r, bool) or r < 0:
        raise InputError(path, f"ILA checkpoint: round is {r!r}, not a round number")
    sd, torch = ck["state_dict"], _torch()
    if not isinstance(sd, dict) or not sd or not all(isinstance(k, str) and isinstance(v, torch.Tensor)
                                                     for k, v in sd.items()):
        raise InputError(path, "ILA checkpoint: state_dict is not a dict of named tensors")
    return ck


def _load_archive(path: Path) -> dict:
    """The dict a ``torch.save`` zip archive holds, loaded with ``weights_only=True``; a missing
    file (named before torch is needed), anything but such an archive, or one holding Python
    objects is refused (unread when it is not an archive)."""
    if not path.exists():
        raise InputError(path, "ILA checkpoint not found")
    if not path.is_file():
        raise InputError(path, "is not a file (expected an ILA checkpoint round_<r>.pt)")
    torch = _torch()
    try:
        is_zip = zipfile.is_zipfile(path)
    except OSError as exc:
        raise InputError(path, f"cannot read the ILA checkpoint ({exc.strerror or exc})") from None
    if not is_zip:
        # fogsim writes torch.save's zip archive; anything else (a bare pickle, random bytes, a
        # truncated copy) is refused unread
        with open(path, "rb") as f:
            if f.read(4) == b"PK\x03\x04":
                raise InputError(path, "truncated or corrupt ILA checkpoint (a torch.save archive without its "
                                       "zip directory); refused unread")
        raise InputError(path, "not an ILA checkpoint: not a torch.save archive (corrupt or another format); "
                               "refused unread")
    try:
        ck = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:
        if "GLOBAL" in str(exc):
            raise InputError(path, "not an ILA checkpoint: holds Python objects, not only tensors and plain data "
                                   "(refused: loading them could run code)") from None
        if str(exc).startswith("Weights only load failed"):
            raise InputError(path, "not an ILA checkpoint: holds data torch's safe loader refuses (not only "
                                   "tensors and plain data); refused") from None
        raise InputError(path, f"not a readable ILA checkpoint (corrupt or truncated: {_first_line(exc)})") from None
    if not isinstance(ck, dict):
        raise InputError(path, f"not an ILA checkpoint: holds a {type(ck).__name__}, not fogsim's dict")
    return ck


def _checkpoint_format(ck: dict, path: Path) -> None:
    """Refuse a checkpoint whose format number is missing, not a number, older or newer than
    :data:`CHECKPOINT_FORMAT` (fogsim 0.1's, which had no number, is format 1)."""
    fmt = ck.get(FORMAT_KEY)
    if fmt is None:
        if {"state_dict", "config", "camera"} <= set(ck):
            fmt = 1  # fogsim 0.1
        else:
            keys = ", ".join(sorted(map(str, ck))[:6]) or "none"
            raise InputError(path, f"not an ILA checkpoint: no {FORMAT_KEY!r} key (keys: {keys})")
    if not isinstance(fmt, int) or isinstance(fmt, bool):
        raise InputError(path, f"not an ILA checkpoint: {FORMAT_KEY} is {fmt!r}, not a number")
    if fmt < CHECKPOINT_FORMAT:
        raise InputError(path, f"written by an older fogsim (format {fmt}); retrain with fogsim ila train")
    if fmt > CHECKPOINT_FORMAT:
        raise InputError(path, f"written by a newer fogsim (format {fmt}; this fogsim reads format "
                               f"{CHECKPOINT_FORMAT}); update fogsim")


def _config_from_dict(c, path: Path) -> ILAConfig:
    """An :class:`ILAConfig` from a checkpoint's config dict: exactly its fields, each of its type."""
    if not isinstance(c, dict):
        raise InputError(path, f"ILA checkpoint: config is a {type(c).__name__}, not a dict")
    known = {f.name: f for f in fields(ILAConfig)}
    extra, missing = sorted(set(map(str, c)) - set(known)), sorted(set(known) - set(c))
    if extra or missing:
        what = "; ".join(s for s in (f"unknown {', '.join(extra)}" if extra else "",
                                     f"missing {', '.join(missing)}" if missing else "") if s)
        raise InputError(path, f"ILA checkpoint: config fields do not match this fogsim's ({what})")
    values = {}
    for name, value in c.items():
        default = getattr(ILAConfig, name, None)
        ok = {bool: lambda v: isinstance(v, bool),
              int: lambda v: isinstance(v, int) and not isinstance(v, bool),
              float: lambda v: isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v),
              str: lambda v: isinstance(v, str),
              tuple: lambda v: isinstance(v, (list, tuple)) and len(v) == 2
              and all(isinstance(x, int) and not isinstance(x, bool) for x in v)}[type(default)](value)
        if not ok:
            raise InputError(path, f"ILA checkpoint: config {name} is {value!r}")
        values[name] = tuple(value) if name == "size" else value
    try:
        return ILAConfig(**values)
    except ValueError as exc:
        raise InputError(path, f"ILA checkpoint: {exc}") from None


def _camera_from_dict(cam, path: Path) -> dict:
    if not isinstance(cam, dict):
        raise InputError(path, f"ILA checkpoint: camera is a {type(cam).__name__}, not a dict")
    out = {}
    for key in ("baseline_m", "fx_over_w"):
        v = cam.get(key)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
            raise InputError(path, f"ILA checkpoint: camera {key} is {v!r}, not a positive number")
        out[key] = float(v)
    return out


@lru_cache(maxsize=2)
def cached_model(checkpoint: str):
    """:func:`load_model`, once per process (for fogging many images)."""
    return load_model(checkpoint)


def load_model(checkpoint: str | Path):
    """(model, config, camera) from a checkpoint written by :func:`train_rounds`.

    Every problem with the file — missing, corrupt, foreign, crafted, of another format, or
    weights that do not fit its config — is an :class:`InputError` naming it.
    """
    ck = read_checkpoint(checkpoint)
    config = ck["config"]
    model = build_unet(config)
    try:
        model.load_state_dict(ck["state_dict"])
    except (RuntimeError, ValueError, TypeError) as exc:
        raise InputError(checkpoint, f"ILA checkpoint: its weights do not fit its config "
                                     f"(width {config.width}, sparse {config.use_sparse}): {_first_line(exc, 240)}"
                         ) from None
    model.to(device()).eval()
    return model, config, ck["camera"]


def predict_depth(model, config: ILAConfig, camera: dict, rgb: np.ndarray,
                  sparse_disparity: np.ndarray | None = None) -> np.ndarray:
    """Planar depth in metres (H×W) for an RGB uint8 image of any size."""
    import cv2

    torch = _torch()
    h, w = rgb.shape[:2]
    x = _unit_rgb(cv2.resize(rgb, config.size, interpolation=cv2.INTER_AREA)).transpose(2, 0, 1)[None]
    x = torch.from_numpy(np.ascontiguousarray(x))
    if config.use_sparse:
        sp = np.zeros((h, w), np.float32) if sparse_disparity is None else sparse_disparity / w
        t = torch.from_numpy(cv2.resize(sp, config.size, interpolation=cv2.INTER_NEAREST)[None, None])
        x = _with_sparse(torch, x, t)
    with torch.no_grad():
        d_over_w = model(x.to(device())).cpu().numpy()[0, 0]
    d_over_w = cv2.resize(d_over_w, (w, h), interpolation=cv2.INTER_LINEAR)
    # d/W and fx/W: the image width cancels, so this is Z = baseline·fx/d at any resolution
    return disparity_to_depth(np.maximum(d_over_w, 1e-6), camera["baseline_m"], camera["fx_over_w"])


@dataclass(frozen=True)
class ILADepth:
    """A :class:`fogsim.readers.base.DepthSpec` reader: planar depth predicted from the image by
    the ILA checkpoint at ``checkpoint`` (``fogsim fog --depth-from ila:CKPT``).

    Picklable (it holds the path only), so worker processes receive it with their samples;
    each process loads the model once (:func:`cached_model`). The fog sidecars record its
    ``name`` as the depth encoding.
    """

    checkpoint: str
    name: ClassVar[str] = "ila"

    def __call__(self, image: np.ndarray) -> tuple[np.ndarray, None]:
        model, config, camera = cached_model(self.checkpoint)
        return predict_depth(model, config, camera, image), None


def ila_fill(checkpoint: str | Path):
    """A :func:`fogsim.fog.fill.register_fill` function that fills holes with the model's depth.

    The sparse disparity the model may take is rebuilt from the valid depth with the
    checkpoint's camera (fx = fx/W · W).
    """
    model, config, camera = load_model(checkpoint)

    def fill(inv: np.ndarray, holes: np.ndarray, image: np.ndarray | None) -> np.ndarray:
        if image is None:
            raise ValueError("the ILA fill needs the RGB image")
        valid_depth = np.divide(1.0, inv, out=np.zeros_like(inv), where=(inv > 0) & ~holes)  # sky, holes → 0
        sparse = depth_to_disparity(valid_depth, camera["baseline_m"], camera["fx_over_w"] * inv.shape[1])
        depth = predict_depth(model, config, camera, image, sparse)
        return np.where(holes, 1.0 / depth, inv).astype(np.float32)

    return fill
