"""The report's figures (matplotlib, Agg backend): the paper's Figs. 7-9 and a calibration plot.

Each function returns a Figure so tests and users can inspect it; ``figure_bytes`` renders it for the report.
"""
from __future__ import annotations

import io
import re

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.ticker import MaxNLocator

from .. import defaults, paper
from ..model.registry import registry
from ..paper import COMBINED

SHAPE_ORDER = ("rectangular", "circular", "sinusoidal", "random", "other")


#: Each format's timestamp and tool entries left out, so a rerun gives the same bytes.
_NO_STAMP = {"png": {"Software": None}, "svg": {"Date": None, "Creator": None},
             "pdf": {"CreationDate": None, "Creator": None, "Producer": None}}
MIME_TYPES = {"png": "image/png", "svg": "image/svg+xml", "pdf": "application/pdf"}
plt.rcParams["svg.hashsalt"] = "roughsense"  # SVG element ids from a fixed salt, not a random one


#: Most pixels one figure is rendered with (a 6000 x 4000 print). ``--dpi 1200`` on the report's widest figures
#: would be 200 Mpx each (3.5 GB and two minutes for a study); a figure beyond the budget is drawn at the dpi that fits.
MAX_FIGURE_PIXELS = 24_000_000


def figure_dpi(figure, dpi: int) -> float:
    """``dpi``, or less for a figure that would exceed :data:`MAX_FIGURE_PIXELS` (said once, as a warning)."""
    import warnings

    from ..errors import RoughsenseWarning

    width_in, height_in = figure.get_size_inches()
    fits = float(np.sqrt(MAX_FIGURE_PIXELS / max(width_in * height_in, 1e-9)))
    if dpi <= fits:
        return dpi
    warnings.warn(RoughsenseWarning(f"--dpi {dpi}: a figure above {MAX_FIGURE_PIXELS / 1e6:g} Mpx is drawn at the "
                                    "resolution that fits that budget"), stacklevel=3)
    return fits


def figure_bytes(figure, figure_format: str = "png", *, dpi: int = defaults.DPI, close: bool = True) -> bytes:
    """Render a figure as PNG, SVG or PDF bytes (no timestamps: reruns give the same bytes), closing it unless told;
    within :data:`MAX_FIGURE_PIXELS`, so memory and time are bounded for every ``dpi`` accepted.

    The margins are trimmed to what is drawn plus ``savefig.pad_inches``. A PNG is drawn once on the canvas and
    trimmed by its pixels; ``savefig``'s tight bounding box would lay the whole figure out a second time (about
    half of a figure's cost), and does so here only for vector formats and for a figure drawn past its edges."""
    if figure_format == "png":
        data = _png_drawn_once(figure, figure_dpi(figure, dpi))
    else:
        data = None
    if data is None:
        buffer = io.BytesIO()
        figure.savefig(buffer, format=figure_format, dpi=figure_dpi(figure, dpi), bbox_inches="tight",
                       metadata=_NO_STAMP[figure_format])
        data = buffer.getvalue()
    if close:
        plt.close(figure)
    return data


def _png_drawn_once(figure, dpi: float) -> bytes | None:
    """The figure drawn once on its Agg canvas, cropped to its ink plus the usual pad, as PNG bytes; None when ink
    touches the canvas's edge (something may be cut off there: the caller takes savefig's tight box, which grows)."""
    from PIL import Image

    before = figure.dpi
    figure.set_dpi(dpi)
    try:
        figure.canvas.draw()
        pixels = np.asarray(figure.canvas.buffer_rgba())
        background = np.round(np.multiply(matplotlib.colors.to_rgba(figure.get_facecolor()), 255)).astype(np.uint8)
        ink = np.any(pixels != background, axis=2)
        rows, columns = np.flatnonzero(ink.any(axis=1)), np.flatnonzero(ink.any(axis=0))
        if not rows.size or rows[0] == 0 or columns[0] == 0 or rows[-1] == ink.shape[0] - 1 \
                or columns[-1] == ink.shape[1] - 1:
            return None
        pad = int(round(plt.rcParams["savefig.pad_inches"] * dpi))
        top, left = max(rows[0] - pad, 0), max(columns[0] - pad, 0)
        cropped = pixels[top:rows[-1] + pad + 1, left:columns[-1] + pad + 1]
        opaque = bool((cropped[..., 3] == 255).all())
        image = Image.fromarray(np.ascontiguousarray(cropped[..., :3] if opaque else cropped))
        buffer = io.BytesIO()
        image.save(buffer, format="PNG", dpi=(dpi, dpi))
        return buffer.getvalue()
    finally:
        figure.set_dpi(before)


#: Colours of a figure's preview on the page: matplotlib's antialiased PNGs use thousands, a plot needs far fewer.
PREVIEW_COLOURS = 128


def page_preview(png: bytes, colours: int = PREVIEW_COLOURS) -> bytes:
    """The PNG embedded in the page: the same pixels reduced to a palette (about a third of the bytes), so the
    self-contained page stays small enough to mail; the full-colour file is kept beside it and linked."""
    from PIL import Image

    image = Image.open(io.BytesIO(png)).convert("RGB")
    # Fast octree and zlib's default level: a plot's few colours need no median cut, and the pair took a fifth of
    # the time of median cut with optimize=True for files as small (benchmarks/bench_study.py's report stage).
    palette = image.quantize(colors=colours, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
    buffer = io.BytesIO()
    palette.save(buffer, format="PNG")
    return buffer.getvalue()


def mark_simulated(figure, text: str):
    """Stamp a figure above its top edge, so a copied image of a simulated study never passes for real data
    (``text``: roughsense.report.provenance.figure_stamp's).

    Above every axes, not in a corner: a corner stamp covered tick and axis labels. The figure grows at the top by
    the stamp's height and every axes keeps its place and size in inches, so a laid-out figure stays laid out
    and the stamp is drawn on the canvas with the rest (no second layout pass to find it).
    """
    width_in, height_in = figure.get_size_inches()
    stamp = figure.text(0.0, 1.0, text, ha="left", va="top", fontsize=9, fontweight="bold", color="#b00020",
                        bbox={"boxstyle": "round,pad=0.25", "fc": "white", "ec": "#b00020", "alpha": 0.9})
    # The box's pad (0.25 font sizes) and edge within the margin a saved figure keeps round its ink (above), and
    # its lower edge where the figure's top was (the layout's own margin below it).
    edge_in = 0.3 * stamp.get_fontsize() / 72.0
    inset_in = plt.rcParams["savefig.pad_inches"] + edge_in
    grown_in = inset_in + stamp.get_window_extent(figure.canvas.get_renderer()).height / figure.dpi + edge_in
    scale = height_in / (height_in + grown_in)
    figure.set_size_inches(width_in, height_in + grown_in)
    for ax in figure.axes:
        box = ax.get_position(original=True)
        ax.set_position([box.x0, box.y0 * scale, box.width, box.height * scale], which="both")
    stamp.set_position((inset_in / width_in, 1.0 - inset_in / (height_in + grown_in)))
    return figure


#: Longest specimen name written upright under a figure's axis (the paper's presets: R2.5, C4.5).
LONGEST_UPRIGHT_TICK = 4


def _specimen_order(specimens, shapes: dict[str, str]) -> list[str]:
    def key(name: str):
        # by shape, then by the name's numbers in order (a preset's period; a spec's period, depth, land): a
        # rectangle rect_4_1_1.2 sorts beside R4, not after R5 as the digits run together (4101.2) would
        shape = shapes.get(name, "other")
        rank = SHAPE_ORDER.index(shape) if shape in SHAPE_ORDER else len(SHAPE_ORDER)
        sizes = tuple(float(number) for number in re.findall(r"\d+(?:\.\d+)?", name))
        return (rank, sizes, name)

    return sorted(dict.fromkeys(specimens), key=key)


def _paper_rows(pad: str, condition: str) -> pd.DataFrame:
    """The paper's per-specimen results for one pad and condition, indexed by specimen (empty if none)."""
    table = paper.paper_results()
    return table[(table.pad == pad) & (table.condition == condition)].set_index("specimen")


def _paper_perceived() -> pd.Series:
    return paper.perceived_roughness().set_index("specimen")["perceived_gmean"]


def spectra_figure(mean_spectra: pd.DataFrame, freq_columns: list[str], pad: str, shapes: dict[str, str]):
    """Fig. 7: mean normalised amplitude spectrum per specimen, one panel per force and shape."""
    data = mean_spectra[mean_spectra["pad"] == pad]
    conditions = list(dict.fromkeys(data["condition"]))
    shape_list = [s for s in SHAPE_ORDER if s in {shapes.get(sp, "other") for sp in data["specimen"]}]
    fig, axes = plt.subplots(len(shape_list), len(conditions), figsize=(4.2 * len(conditions), 3.0 * len(shape_list)),
                             squeeze=False, sharex=True, sharey=True)
    freq = np.array([float(c) for c in freq_columns])
    for row, shape in enumerate(shape_list):
        names = [s for s in _specimen_order(data["specimen"], shapes) if shapes.get(s, "other") == shape]
        colours = plt.cm.viridis(np.linspace(0, 0.9, max(len(names), 1)))
        for col, condition in enumerate(conditions):
            ax = axes[row, col]
            for colour, name in zip(colours, names):
                line = data[(data["specimen"] == name) & (data["condition"] == condition)]
                if len(line):
                    ax.plot(freq, line[freq_columns].to_numpy()[0], color=colour, lw=1.2, label=name)
            ax.set_title(f"{pad} pad, {condition}, {shape}", fontsize=9)
            ax.grid(alpha=0.3)
            if row == len(shape_list) - 1:
                ax.set_xlabel("spatial frequency (mm$^{-1}$)")
            if col == 0:
                ax.set_ylabel("normalised amplitude")
        axes[row, -1].legend(fontsize=7, ncol=2, loc="upper right")
    fig.tight_layout()
    return fig


def cv_curves_figure(cv_table: pd.DataFrame, chosen: pd.DataFrame):
    """Fig. 8: cross-validated RMSE against the number of components, one panel per CV scheme and pad."""
    pads = list(dict.fromkeys(cv_table["pad"]))
    schemes = list(dict.fromkeys(cv_table["cv"]))
    conditions = list(dict.fromkeys(cv_table["condition"]))
    fig, axes = plt.subplots(len(schemes), len(pads), figsize=(6.0 * len(pads), 3.6 * len(schemes)),
                             squeeze=False, sharex=True)
    colours = dict(zip(conditions, plt.cm.tab10.colors))
    for row, cv in enumerate(schemes):
        for ax, pad in zip(axes[row], pads):
            for condition in conditions:
                curve = cv_table[(cv_table.pad == pad) & (cv_table.cv == cv) & (cv_table.condition == condition)]
                curve = curve[curve["n_components"] >= 1]
                if curve.empty:
                    continue
                ax.plot(curve["n_components"], curve["rmse"], "-", color=colours[condition], lw=1.3, label=condition)
                pick = chosen[(chosen.pad == pad) & (chosen.condition == condition) & (chosen.cv == cv)]
                if len(pick):
                    n = int(pick["best_n_components"].iloc[0])
                    value = curve.loc[curve["n_components"] == n, "rmse"]
                    if len(value):
                        ax.plot([n], [float(value.iloc[0])], "o", mfc="none", mec="red", ms=9)
            ax.set_title(f"{pad} pad, {cv.upper()}")
            ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # a component count is a whole number
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7, ncol=2)
            if row == len(schemes) - 1:
                ax.set_xlabel("number of PLS components")
        axes[row, 0].set_ylabel("cross-validated RMSE")
    fig.tight_layout()
    return fig


def ovl_sd_figure(results: pd.DataFrame, perceived: pd.DataFrame, pad: str, shapes: dict[str, str], *,
                  paper: bool = True):
    """Fig. 9: OVL per specimen (top) and SD of perception vs predictions (bottom), per shape.

    ``paper=False`` leaves the paper's values out (a study whose design is not the paper's, or LOSO results).
    """
    data = results[results["pad"] == pad]
    shape_list = [s for s in SHAPE_ORDER if s in {shapes.get(sp, "other") for sp in data["specimen"]}]
    conditions = list(dict.fromkeys(data["condition"]))
    fig, axes = plt.subplots(2, len(shape_list), figsize=(5.0 * len(shape_list), 6.0), squeeze=False)
    human_sd = perceived.set_index("specimen")["sd"]
    for col, shape in enumerate(shape_list):
        names = [s for s in _specimen_order(data["specimen"], shapes) if shapes.get(s, "other") == shape]
        x = np.arange(len(names))
        for condition, marker in zip(conditions, "osD^v"):
            rows = data[data["condition"] == condition].set_index("specimen").reindex(names)
            axes[0, col].plot(x, rows["ovl"], marker=marker, lw=1, label=condition)
            axes[1, col].plot(x, rows["pred_sd"], marker=marker, lw=1, label=f"prediction {condition}")
        axes[1, col].plot(x, human_sd.reindex(names), "k-", marker="*", lw=2, label="participants")
        published = _paper_rows(pad, COMBINED).reindex(names)
        if paper and published["ovl"].notna().any():
            axes[0, col].plot(x, published["ovl"], ":", color="0.45", marker=".", lw=1.5, label="paper, combined")
        for row, label in ((0, "OVL"), (1, "SD")):
            # specs' names (rect_4_1_1.2) are longer than the presets' (R4): slanted so that they stay apart
            slanted = any(len(name) > LONGEST_UPRIGHT_TICK for name in names)
            axes[row, col].set_xticks(x, names, **({"rotation": 45, "ha": "right", "fontsize": 8} if slanted else {}))
            axes[row, col].set_ylabel(label)
            axes[row, col].grid(alpha=0.3)
            axes[row, col].set_title(f"{pad} pad, {shape}: {label}", fontsize=9)
        axes[0, col].set_ylim(0, 1)
        axes[0, col].legend(fontsize=7)
        axes[1, col].legend(fontsize=7)
    fig.tight_layout()
    return fig


def predicted_vs_perceived_figure(results: pd.DataFrame, perceived: pd.DataFrame, cv: str, *, paper=True):
    """Predicted mean ± SD against perceived roughness, with the identity line.

    The paper's (LOO) predictions are drawn only beside LOO results, and only for the pads ``paper`` allows
    (True: all; False: none; or a collection of pad names).
    """
    def allowed(pad: str) -> bool:
        return cv == "loo" and (paper is True or (paper is not False and pad in paper))

    pads = list(dict.fromkeys(results["pad"]))
    conditions = list(dict.fromkeys(results["condition"]))
    fig, axes = plt.subplots(1, len(pads), figsize=(5.0 * len(pads), 4.6), squeeze=False, sharey=True)
    truth = perceived.set_index("specimen")["gmean"]
    top = float(np.nanmax([truth.max(), (results["pred_mean"] + results["pred_sd"]).max()])) * 1.08
    for ax, pad in zip(axes[0], pads):
        ax.plot([0, top], [0, top], color="0.5", lw=1, label="identity")
        for offset, (condition, marker) in zip(np.linspace(-0.02, 0.02, len(conditions)), zip(conditions, "osD^v")):
            rows = results[(results.pad == pad) & (results.condition == condition)]
            x = truth.reindex(rows["specimen"]).to_numpy() + offset
            ax.errorbar(x, rows["pred_mean"], yerr=rows["pred_sd"], fmt=marker, ms=4, capsize=2, lw=0.8, label=condition)
        published = _paper_rows(pad, COMBINED) if allowed(pad) else pd.DataFrame()
        if len(published):
            ax.plot(_paper_perceived().reindex(published.index), published["pred_mean"], "x", color="0.45", ms=5,
                    label="paper, combined")
        _predicted_vs_perceived_axes(ax, top, f"{pad} pad ({cv.upper()})")
        ax.legend(fontsize=7)
    axes[0, 0].set_ylabel("predicted roughness (mean ± SD)")
    fig.tight_layout()
    return fig


def _predicted_vs_perceived_axes(ax, top: float, title: str) -> None:
    """Square axes from 0 to ``top`` on both scales, so the identity line is the diagonal a reader expects."""
    ax.set_xlim(0, top)
    ax.set_ylim(0, top)
    ax.set_aspect("equal")
    ax.set_xlabel("perceived roughness (geometric mean)")
    ax.set_title(title)
    ax.grid(alpha=0.3)


def unseen_figure(results: pd.DataFrame, perceived: pd.DataFrame, condition: str):
    """Surfaces never seen: each specimen's LOSO prediction (mean ± SD) against its perceived roughness.

    One panel per pad, every model in ``results`` (results_loso rows, with their model column) at ``condition``;
    each point carries the specimen's name, so a reader sees which surfaces a model gets wrong, not only how many.
    """
    rows = results[results["condition"] == condition]
    pads = list(dict.fromkeys(rows["pad"]))
    models = list(dict.fromkeys(rows["model"]))
    fig, axes = plt.subplots(1, max(len(pads), 1), figsize=(5.6 * max(len(pads), 1), 5.2), squeeze=False, sharey=True)
    truth = perceived.set_index("specimen")["gmean"]
    top = float(np.nanmax([truth.max(), (rows["pred_mean"] + rows["pred_sd"]).max()])) * 1.1
    styles = {f.name: (f.marker, f.colour) for f in registry()}  # a family the registry does not know: grey diamonds
    for ax, pad in zip(axes[0], pads):
        ax.plot([0, top], [0, top], color="0.5", lw=1, label="identity")
        for model in models:
            marker, colour = styles.get(model, ("D", "0.3"))
            data = rows[(rows.pad == pad) & (rows.model == model)]
            x = truth.reindex(data["specimen"]).to_numpy()
            ax.errorbar(x, data["pred_mean"], yerr=data["pred_sd"], fmt=marker, color=colour, ms=4, capsize=2,
                        lw=0.8, label=model)
            for xi, yi, name in zip(x, data["pred_mean"], data["specimen"]):
                ax.annotate(str(name), (xi, yi), xytext=(3, 3), textcoords="offset points", fontsize=6.5, color=colour)
        _predicted_vs_perceived_axes(ax, top, f"{pad} pad, {condition}, leave-one-specimen-out")
        ax.legend(fontsize=7, loc="upper left")
    axes[0, 0].set_ylabel("predicted roughness of the unseen specimen (mean ± SD)")
    fig.tight_layout()
    return fig


def line_spectrum_figure(line, px_per_mm: float, freq_per_mm, amplitude, title: str, contact=None):
    """One image: the gray level along its contact line (top), its contact band with the lands and grooves read
    (middle, with ``contact``: a ``(band profile, ContactReading)`` pair from sensor/contact_geometry.py) and its
    normalised spectrum with the peak marked (bottom).

    What ``roughsense features --plot`` draws, so a user can see where the spectrum's peak and the widths come from.
    """
    rows = 2 if contact is None else 3
    fig, axes = plt.subplots(rows, 1, figsize=(8.0, 2.8 * rows))
    top, bottom = axes[0], axes[-1]
    x_mm = np.arange(len(line)) / px_per_mm
    top.plot(x_mm, line, color="0.25", lw=0.8)
    top.set_xlabel("position along the line (mm)")
    top.set_ylabel("gray level (0-1)")
    top.set_title(title, fontsize=9)
    if contact is not None:
        _contact_panel(axes[1], *contact, px_per_mm)
    freq, amplitude = np.asarray(freq_per_mm, float), np.asarray(amplitude, float)
    peak = int(np.argmax(amplitude))
    bottom.plot(freq, amplitude, "-o", color="#2f5d8a", ms=3, lw=1.2)
    bottom.plot([freq[peak]], [amplitude[peak]], "o", mfc="none", mec="red", ms=11)
    bottom.annotate(f"peak {freq[peak]:.3f} mm$^{{-1}}$ (wavelength {1 / freq[peak]:.2f} mm)", (freq[peak], amplitude[peak]),
                    xytext=(8, -4), textcoords="offset points", color="red", fontsize=8, va="top")
    bottom.set_xlabel("spatial frequency (mm$^{-1}$)")
    bottom.set_ylabel("normalised amplitude")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def _contact_panel(ax, profile, reading, px_per_mm: float) -> None:
    """The band profile, what the widths were read on and its threshold, each complete land (contact) and groove
    (gap) shaded, and the widths written (or why there are none)."""
    ax.plot(np.arange(len(profile)) / px_per_mm, profile, color="0.55", lw=0.6, label="band (rows averaged)")
    if reading.read_on is not None:
        read_x_mm = (np.arange(len(reading.read_on)) + 0.5) * reading.step_mm - 0.5 / px_per_mm
        ax.plot(read_x_mm, reading.read_on, color="#2f5d8a", lw=0.9, label="read on (pairs of px; crest envelope on a "
                "ridged pad)")
        if reading.threshold is not None:
            ax.plot(read_x_mm, reading.threshold, color="#b8860b", lw=0.8, ls="--", label="contact / gap threshold")
    for start, stop in reading.lands_mm:
        ax.axvspan(start, stop, color="#3a9a4a", alpha=0.25, lw=0)
    for start, stop in reading.grooves_mm:
        ax.axvspan(start, stop, color="#c0504d", alpha=0.15, lw=0)
    values = reading.as_dict()
    if np.isfinite(values["land_mm"]):
        text = (f"land (contact, green) {values['land_mm']:.2f} mm, groove (gap, red) {values['groove_mm']:.2f} mm "
                f"(+-{values['width_se_mm']:.3f} mm), land fraction {100 * values['land_fraction']:.0f} %, "
                f"{len(reading.lands_mm)} lands / {len(reading.grooves_mm)} grooves")
    else:
        text = "land and groove not readable with confidence (NaN): no regular contact pattern"
    ax.set_title(text, fontsize=8)
    ax.set_xlabel("position along the line (mm)")
    ax.set_ylabel("gray level (0-1)")
    ax.legend(fontsize=7, loc="lower right")
