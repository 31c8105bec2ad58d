"""A still of the live view, for where nobody watches it live (a notebook run headless: the docs
build, the test suite): each technique's image and lanes picture as they were at the last frame,
drawn with matplotlib as a PNG."""
import io

from toolkit.demo.efficiency import talk_figure


def still_png(snapshot):
    """PNG bytes: per technique (a column) its image over its lanes picture, with spp, RMSE and
    SIMD efficiency (and the talk's figure) in the titles."""
    from matplotlib.figure import Figure     # imported here: only a still needs matplotlib
    frames = list(snapshot.frames.values())
    fig = Figure(figsize=(3.6 * max(1, len(frames)), 7.4), constrained_layout=True)
    axes = fig.subplots(2, max(1, len(frames)), squeeze=False)
    for column, frame in enumerate(frames):
        rmse = f", RMSE {frame.rmse:.4f}" if frame.rmse is not None else ""
        axes[0, column].imshow(frame.rgba)
        axes[0, column].set_title(f"{frame.technique}\n{frame.spp:,.0f} spp{rmse}", fontsize=9)
        axes[1, column].imshow(frame.lanes, aspect="auto", interpolation="nearest")
        figures = []
        for phase, value in frame.efficiency.items():
            talk = talk_figure(frame.technique, phase)
            figures.append(f"{phase} {value:.0%}" + (f" (talk ~{talk:.0%})" if talk is not None else ""))
        lines = [", ".join(figures[i:i + 2]) for i in range(0, len(figures), 2)]
        axes[1, column].set_title("SIMD efficiency\n" + "\n".join(lines), fontsize=7)
        axes[1, column].set_xlabel(f"lanes of the sampled warps (W = {snapshot.warp_width})")
        axes[1, column].set_ylabel("step (newest at the bottom)")
        axes[0, column].set_xticks([])
        axes[0, column].set_yticks([])
        axes[1, column].set_xticks([])
        axes[1, column].set_yticks([])
    out = io.BytesIO()
    fig.savefig(out, format="png", dpi=90)
    return out.getvalue()
