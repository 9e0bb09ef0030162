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
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import ClassVar

import numpy as np

from fogsim.camera import depth_to_disparity, disparity_to_depth
from fogsim.errors import FogsimError, InputError
from fogsim.fileio import read_image
from fogsim.readers.cityscapes import cityscapes_samples, read_cityscapes_disparity


def _torch():
    try:
        import torch
    except ImportError:
        raise FogsimError("ILA needs PyTorch: pip install -e \".[ila]\" (CPU: pip install torch==2.13.0)") from None
    return torch


@dataclass(frozen=True)
class ILAConfig:
    width: int = 16             # channels of the first U-Net level (reference: 64)
    size: tuple[int, int] = (256, 128)  # training resolution W×H (reference: 480×320)
    use_sparse: bool = False    # also feed the sparse disparity and its validity mask
    sparse_drop: float = 0.3    # share of the sparse input hidden (in blobs) per training batch
    loss_on: str = "valid"      # "valid" (masked) or "all" (the reference: holes → 0)
    loss: str = "mse"           # "mse" of d/W (the reference) or "log_l1": |log d − log d*| (relative)
    rounds: int = 2
    epochs: int = 4
    batch: int = 4
    lr: float = 1e-3
    seed: int = 0

    def __post_init__(self):
        if self.size[0] % 16 or self.size[1] % 16:
            raise ValueError(f"ILA size must be multiples of 16 (four 2× poolings), got {self.size}")
        if self.loss_on not in ("valid", "all"):
            raise ValueError(f"loss_on must be 'valid' or 'all', got {self.loss_on!r}")
        if self.loss not in ("mse", "log_l1"):
            raise ValueError(f"loss must be 'mse' or 'log_l1', got {self.loss!r}")


@dataclass
class StereoSet:
    """Images and normalised disparity targets (d/W, 0 = hole) at the training size."""

    rgb: np.ndarray                # N×3×H×W float32 in [0, 1]
    target: np.ndarray             # N×1×H×W float32, d/W
    original_valid: np.ndarray     # N×1×H×W bool: valid in the stereo input
    keys: list[str] = field(default_factory=list)
    camera: dict = field(default_factory=dict)  # baseline_m, fx_over_w


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
        rgbs.append(cv2.resize(img, size, interpolation=cv2.INTER_AREA).transpose(2, 0, 1) / np.float32(255))
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
        torch.save({"state_dict": {k: v.cpu() for k, v in model.state_dict().items()},
                    "config": asdict(config), "camera": data.camera,
                    "round": r, "output": "disparity / image width"},
                   out / f"round_{r}.pt")
        target = filled
        log.append(entry)
    return log


@lru_cache(maxsize=2)
def cached_model(checkpoint: str):
    """:func:`load_model`, once per process (for fogging many images)."""
    if not Path(checkpoint).is_file():
        raise InputError(checkpoint, "ILA checkpoint not found")
    return load_model(checkpoint)


def load_model(checkpoint: str | Path):
    """(model, config, camera) from a checkpoint written by :func:`train_rounds`."""
    torch = _torch()
    ck = torch.load(checkpoint, map_location="cpu", weights_only=False)
    c = ck["config"]
    config = ILAConfig(**{**c, "size": tuple(c["size"])})
    model = build_unet(config)
    model.load_state_dict(ck["state_dict"])
    model.to(device()).eval()
    return model, config, ck["camera"]


def predict_depth(model, config: ILAConfig, camera: dict, rgb: np.ndarray,
                  sparse_disparity: np.ndarray | None = None) -> np.ndarray:
    """Planar depth in metres (H×W) for an RGB uint8 image of any size."""
    import cv2

    torch = _torch()
    h, w = rgb.shape[:2]
    x = cv2.resize(rgb, config.size, interpolation=cv2.INTER_AREA).transpose(2, 0, 1)[None] / np.float32(255)
    x = torch.from_numpy(x.astype(np.float32))
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
    """A :func:`fogsim.fill.register_fill` function that fills holes with the model's depth.

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
