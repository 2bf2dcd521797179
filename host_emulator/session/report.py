"""`session report FILE`: report.md and plots of a board recording, without truth.

What the board sent is all there is: the 52-byte frames (state, attitude, velocity, position,
the GNSS fix they carry) and the extended frames (covariance, biases, health and its causes,
the origin of the local frame, the navigator's tick). Decoded with common/proto/stream.py;
sampled, as an emulator run is scored, where an extended frame follows its 52-byte frame
(eval/evaluate.py track). The session clock is the extended frames' tick (5 ms): a tick that
goes back is a restart of the board, and the clock carries on from where it was.

    trajectory.png  the firmware's track (navigating) over the GNSS fixes the frames carry
    sigma.png       the reported 3-sigma of position and velocity (the covariance diagonal)
    state.png       attitude and velocity over time
    health.png      health level and which causes were set, over time
    biases.png      bias estimates with 3-sigma (eval/report.py's)
Restarts are marked in every time plot.
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pymap3d

from common.proto import config as board_config
from common.proto import records, session_file, stream
from common.proto.session_file import SessionError
from common.proto.stimulus import TICK_US
from host_emulator.eval import evaluate, report

TICK_S = TICK_US * 1e-6
NAVIGATING = evaluate.NAVIGATING
PLOTS = ("trajectory.png", "sigma.png", "state.png", "health.png", "biases.png")
HEALTH = ("normal", "warning", "fault")


@dataclass(eq=False)
class SessionRun:
    """A decoded recording: the track at the extended frames on the session clock, and the
    figures of the whole stream."""

    name: str
    header: dict
    problems: list  # what the session file lost (session_file.Session.problems)
    tr: evaluate.Track  # t_s on the session clock
    restarts: list  # session times at which the board started again
    fixes: np.ndarray  # (K, 3) distinct GNSS fixes in the track's ENU frame
    counts: dict  # StreamDecoder.counts()
    frame_states: np.ndarray  # (N,) nav_state of every 52-byte frame
    every: int  # output_every_ticks: ticks per 52-byte frame


def load(path):
    """The SessionRun of the session file (or plain capture) at path; SessionError if nothing
    in it decodes as the board's output."""
    s = session_file.load(path)
    dec = stream.StreamDecoder()
    decoded = stream.Decoded()
    lists = {stream.FRAME: decoded.frames, stream.EXT: decoded.ext, stream.RAW: decoded.raw}
    for kind, fields in dec.feed(s.data) + dec.finish():
        lists[kind].append(fields)
    if not decoded.frames or not any(e["frame_index"] >= 0 for e in decoded.ext):
        raise SessionError(
            f"{path}: no board output in it ({len(decoded.frames)} frames, "
            f"{len(decoded.ext)} extended frames decode): not a recording of the board?"
        )
    origin = _origin(decoded)
    tr = evaluate.track(decoded, TICK_S, origin)
    tr.t_s, restarts = session_clock(tr.t_s)
    return SessionRun(
        name=Path(path).name,
        header=s.header,
        problems=s.problems(str(path)),
        tr=tr,
        restarts=restarts,
        fixes=_fixes(decoded.frames, origin),
        counts=dec.counts(),
        frame_states=np.array([f["nav_state"] for f in decoded.frames], int),
        every=_output_every(s.header),
    )


def _output_every(header):
    """The recording's output_every_ticks: its configuration's, else the firmware default."""
    try:
        return int(board_config.from_values(header.get("config") or {}).output_every_ticks)
    except board_config.ConfigError:
        return int(board_config.from_values({}).output_every_ticks)


def _origin(decoded):
    """(lat_e7, lon_e7, h_m) of the plots' ENU frame: the first origin an extended frame
    sends, else the first GNSS fix, else 0 (a board that never had a fix)."""
    for e in decoded.ext:
        if e["origin_lat_e7"] or e["origin_lon_e7"]:
            return e["origin_lat_e7"], e["origin_lon_e7"], e["origin_h_m"]
    for f in decoded.frames:
        if f["gnss_valid"]:
            return f["lat_e7"], f["lon_e7"], f["height_m"]
    return 0, 0, 0.0


def session_clock(t):
    """(t on one clock, [restart times]): where the tick goes back the board restarted, and
    the clock carries on from the last time before it (plus one sample step)."""
    t = np.asarray(t, float).copy()
    restarts = []
    back = np.flatnonzero(np.diff(t) < 0) + 1
    for i in back:
        step = t[i - 1] - t[i - 2] if i >= 2 else 0.1
        shift = t[i - 1] + step - t[i]
        t[i:] += shift
        restarts.append(float(t[i]))
    return t, restarts


def _fixes(frames, origin):
    """(K, 3) ENU positions of the distinct valid GNSS fixes the frames carry."""
    pts = [(f["lat_e7"], f["lon_e7"], f["height_m"]) for f in frames if f["gnss_valid"]]
    if not pts:
        return np.zeros((0, 3))
    a = np.array(pts, float)
    keep = np.ones(len(a), bool)
    keep[1:] = np.any(a[1:] != a[:-1], axis=1)  # a fix repeats in every frame until the next
    a = a[keep]
    e, n, u = pymap3d.geodetic2enu(a[:, 0] * 1e-7, a[:, 1] * 1e-7, a[:, 2],
                                   origin[0] * 1e-7, origin[1] * 1e-7, origin[2])  # fmt: skip
    return np.stack([e, n, u], axis=-1)


def figures(run):
    """The summary figures of report.md, from the whole stream and the extended frames."""
    tr, c = run.tr, run.counts
    frame_s = run.every * TICK_S
    nav_frames = int(np.count_nonzero(run.frame_states == NAVIGATING))
    first_nav = np.flatnonzero(tr.state == NAVIGATING)
    return {
        "duration_s": float(tr.t_s[-1] - tr.t_s[0] + (tr.t_s[1] - tr.t_s[0]))
        if len(tr.t_s) > 1
        else 0.0,
        "frames": c["frames"],
        "ext_frames": c["ext"],
        "raw_records": c["raw"],
        "dropped_frames": c["dropped_frames"],
        "bad_checksum": c["bad_checksum"],
        "bad_crc": c["bad_crc"],
        "skipped_bytes": c["skipped_bytes"],
        "starts": len(run.restarts) + 1,
        "navigating_s": nav_frames * frame_s,
        "navigating_share": nav_frames / len(run.frame_states),
        "first_navigating_s": float(tr.t_s[first_nav[0]]) if first_nav.size else None,
        "health_share": {h: float(np.mean(tr.health == i)) for i, h in enumerate(HEALTH)},
        "cause_share": {
            name: float(np.mean((tr.causes & bit) != 0))
            for bit, name in records.CAUSES
            if np.any(tr.causes & bit)
        },
        "gnss_fixes": len(run.fixes),
    }


def markdown(run, fig):
    """report.md of a recording."""
    h = run.header
    src = ", ".join(f"{k} {h[k]}" for k in ("source", "started_utc", "baud") if h.get(k))
    lines = [f"# Board recording: {run.name}", ""]
    lines += [
        "What the board sent, decoded (common/proto/stream.py): there is no truth, so these "
        "are the board's own figures: its track, the 3-sigma it reports, its state and health."
        + (f" Recorded from {src}." if src else ""),
        "",
    ]
    lines += [f"- Warning: {p}" for p in run.problems]
    lines += ["", "| figure | value |", "|---|---|"]
    rows = [
        ("duration", report.fmt(fig["duration_s"], 1, "s")),
        ("52-byte frames", fig["frames"]),
        ("extended frames", fig["ext_frames"]),
        ("raw-input records", fig["raw_records"]),
        ("dropped frames (counter gaps; a restart adds one)", fig["dropped_frames"]),
        ("checksum / CRC failures", f"{fig['bad_checksum']} / {fig['bad_crc']}"),
        ("undecodable bytes", fig["skipped_bytes"]),
        ("board starts in the recording", fig["starts"]),
        ("time navigating", f"{fig['navigating_s']:.1f} s ({100 * fig['navigating_share']:.1f} %)"),
        ("first navigating", report.fmt(fig["first_navigating_s"], 1, "s")),
        ("distinct GNSS fixes", fig["gnss_fixes"]),
    ]
    lines += [f"| {k} | {v} |" for k, v in rows]
    lines += ["", "| health (docs/health.md) | share of the extended frames |", "|---|---|"]
    lines += [f"| {k} | {100 * v:.1f} % |" for k, v in fig["health_share"].items()]
    if fig["cause_share"]:
        lines += ["", "| cause | share of the extended frames |", "|---|---|"]
        lines += [f"| {k} | {100 * v:.1f} % |" for k, v in fig["cause_share"].items()]
    lines += ["", "## Plots", ""]
    for p in PLOTS:
        lines += [f"![{p[:-4]}]({p})", ""]
    return "\n".join(lines)


def _restarts(ax, restarts):
    for i, t in enumerate(restarts):
        ax.axvline(t, color="k", ls="--", lw=0.9, label="board restart" if i == 0 else None)


def trajectory_figure(plt, title, run):
    """The track while navigating over the GNSS fixes; where the board (re)started."""
    tr = run.tr
    fig, ax = plt.subplots(figsize=(8, 7))
    if len(run.fixes):
        ax.plot(run.fixes[:, 0], run.fixes[:, 1], ".", ms=2, color="C2", label="GNSS fixes")
    nav = tr.state == NAVIGATING
    track = np.where(nav[:, None], tr.p_n, np.nan)  # gaps where it was not navigating
    ax.plot(track[:, 0], track[:, 1], color="C0", lw=0.9, label="firmware (navigating)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("East, m")
    ax.set_ylabel("North, m")
    ax.set_title(f"{title}: track")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def sigma_figure(plt, title, run):
    """The reported 3-sigma of position and velocity, E N U, scaled to the settled part."""
    tr = run.tr
    fig, axs = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    for ax, idx, unit in ((axs[0], 0, "position 3-sigma, m"), (axs[1], 3, "velocity 3-sigma, m/s")):
        nav = tr.state == NAVIGATING  # aligning, the board reports no covariance
        s3 = 3 * tr.sigma[nav, idx : idx + 3]
        for j, name in enumerate("ENU"):
            ax.plot(tr.t_s[nav], s3[:, j], ".", ms=1, color=f"C{j}", label=name)
        k = report.settled_from(s3)
        top = 1.2 * float(np.max(s3[k:])) if len(s3[k:]) else 1.0
        if len(s3) and np.max(s3) > top:
            report.mark_startup(ax, tr.t_s[nav], k)
        ax.set_ylim(0, top if top > 0 else 1.0)
        _restarts(ax, run.restarts)
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, ncol=5, loc="upper right")
    axs[0].set_title(f"{title}: the reported 3-sigma (extended frames' covariance)")
    axs[1].set_xlabel("session time, s")
    return fig


def state_figure(plt, title, run):
    """Yaw (unwrapped), pitch and roll, and the ENU velocity, over time."""
    tr = run.tr
    deg = 180.0 / np.pi
    fig, axs = plt.subplots(3, 1, figsize=(10, 9), sharex=True)
    _, yaw = report.yaw_for_plot(tr.t_s, np.full(len(tr.t_s), np.nan), tr.t_s, tr.ypr[:, 0])
    axs[0].plot(tr.t_s, yaw * deg, color="C0", lw=0.8, label="yaw")
    axs[0].set_ylabel("yaw, deg (unwrapped)")
    axs[1].plot(tr.t_s, tr.ypr[:, 1] * deg, color="C1", lw=0.8, label="pitch")
    axs[1].plot(tr.t_s, tr.ypr[:, 2] * deg, color="C2", lw=0.8, label="roll")
    axs[1].set_ylabel("deg")
    for j, name in enumerate("ENU"):
        axs[2].plot(tr.t_s, tr.v_n[:, j], color=f"C{j}", lw=0.8, label=f"{name} velocity")
    axs[2].set_ylabel("m/s")
    nav = tr.state == NAVIGATING
    for ax in axs:
        ax.fill_between(tr.t_s, 0, 1, where=~nav, transform=ax.get_xaxis_transform(),
                        color="0.5", alpha=0.15, lw=0, label="not navigating")  # fmt: skip
        _restarts(ax, run.restarts)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, ncol=4, loc="best")
    axs[0].set_title(f"{title}: attitude and velocity")
    axs[2].set_xlabel("session time, s")
    return fig


def health_figure(plt, title, run):
    """Health level (0 normal, 1 warning, 2 fault) and one row per cause that was set."""
    tr = run.tr
    fig, axs = plt.subplots(2, 1, figsize=(10, 7), sharex=True, height_ratios=(1, 2))
    axs[0].step(tr.t_s, tr.health, where="post", color="C3", lw=1.0, label="health")
    axs[0].step(tr.t_s, tr.state, where="post", color="C0", lw=0.8, label="nav state")
    axs[0].set_yticks([0, 1, 2], ["0 normal / -", "1 warning / aligning", "2 fault / navigating"])
    axs[0].set_ylim(-0.3, 2.3)
    present = [(bit, name) for bit, name in records.CAUSES if np.any(tr.causes & bit)]
    for row, (bit, _) in enumerate(present):
        on = (tr.causes & bit) != 0
        axs[1].fill_between(tr.t_s, row - 0.4, row + 0.4, where=on, step="post",
                            color=f"C{row % 10}", lw=0)  # fmt: skip
    axs[1].set_yticks(range(len(present)), [name for _, name in present])
    axs[1].set_ylim(-0.6, max(len(present), 1) - 0.4)
    if not present:
        axs[1].text(0.5, 0.5, "no cause was ever set", transform=axs[1].transAxes, ha="center")
    for ax in axs:
        _restarts(ax, run.restarts)
        ax.grid(alpha=0.3)
    axs[0].legend(fontsize=7, loc="upper right")
    axs[0].set_title(f"{title}: health and its causes (docs/health.md)")
    axs[1].set_xlabel("session time, s")
    return fig


def plots(out_dir, title, run):
    """Write PLOTS into out_dir."""
    plt = report.pyplot()
    tr = run.tr
    nav = tr.state == NAVIGATING
    built = (
        trajectory_figure(plt, title, run),
        sigma_figure(plt, title, run),
        state_figure(plt, title, run),
        health_figure(plt, title, run),
        report.biases_figure(plt, title, tr, nav, None, (), float(tr.t_s[-1])),
    )
    for ax in built[-1].axes:
        _restarts(ax, run.restarts)
    for name, fig in zip(PLOTS, built, strict=True):
        report.save_figure(plt, fig, Path(out_dir) / name)


def write(path, out_dir=None):
    """report.md and PLOTS of the recording at path into out_dir (default: beside it, in
    NAME-report/); returns (out_dir, figures)."""
    run = load(path)
    out = Path(out_dir) if out_dir else Path(path).with_name(Path(path).stem + "-report")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise SessionError(f"cannot create output directory {out}: {e.strerror}") from None
    fig = figures(run)
    plots(out, run.name, run)
    (out / "report.md").write_text(markdown(run, fig))
    return out, fig
