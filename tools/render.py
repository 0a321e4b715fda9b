#!/usr/bin/env python3
"""Pictures of a run without knowing ParaView: its snapshots as PNG frames and an animation.

    tools/render.py OUT_DIR [--png FILE] [--time T] [--frames DIR] [--gif FILE] [--color FIELD]
                            [--size W H] [--view iso|front|side|top]

Reads OUT_DIR/snapshots.pvd (a run with output.snapshot_interval > 0 and the default
output.format "vtk" or "vtk_ascii"), draws every grain as a sphere of its radius coloured by FIELD
(speed, mode, group, material, radius, id; default speed) and every wall as a translucent surface
(2D: lines), and writes one PNG (the snapshot nearest --time, default the last: OUT_DIR/render.png
unless --png), or with --frames every snapshot as DIR/frame_NNNNNN.png, and with --gif an animated
GIF of them. It runs ParaView's pvbatch offscreen (Debian's paraview package, installed by
tools/install-deps.sh). Without a display it starts its own virtual one (Xvfb, which picks a free
display number itself), falling back to xvfb-run when Xvfb is not on PATH. Without ParaView it says
so and exits with status 3.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import select
import shutil
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

FIELDS = ["speed", "mode", "group", "material", "radius", "id"]
INNER = "MATEP_RENDER_INNER"


@contextlib.contextmanager
def virtual_display(timeout: float = 30.0):
    """A private X display for pvbatch: yields the DISPLAY string (None when none could be started).

    Xvfb is asked to choose a free display number itself and to write it to a pipe once it accepts
    connections (-displayfd), so there is neither the race of xvfb-run -a (two servers taking the same
    number, or a stale socket left by a killed server under a free lock) nor a wait guessed in
    seconds: both failed a render once on a loaded 2-core machine. -noreset: an X server resets
    when its last client leaves, and refuses connections while it does; pvbatch connects more than
    once, and the render test's pictures share one server, so on a loaded machine a connection came
    during a reset ("bad X server connection"). With four busy loops on the server's core, the
    first of four pictures drawn one after the other on one display failed, and so did one or two
    of the render test's cases a round, each after three fresh servers (six in a trial: the same);
    with -noreset all four pictures and all nine cases of three rounds drew."""
    xvfb = shutil.which("Xvfb")
    if not xvfb:
        yield None
        return
    rfd, wfd = os.pipe()
    proc = subprocess.Popen([xvfb, "-displayfd", str(wfd), "-screen", "0", "1280x1024x24", "-nolisten", "tcp",
                             "-noreset"],
                            pass_fds=(wfd,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(wfd)
    number = b""
    deadline = time.monotonic() + timeout
    try:
        while not number.endswith(b"\n") and time.monotonic() < deadline and proc.poll() is None:
            ready, _, _ = select.select([rfd], [], [], 0.5)
            if ready:
                chunk = os.read(rfd, 64)
                if not chunk:
                    break
                number += chunk
        os.close(rfd)
        yield f":{int(number)}" if number.strip().isdigit() and proc.poll() is None else None
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def frames_of(out_dir: Path) -> list[tuple[float, str, list[str]]]:
    """(time, grains' file, walls' files) of each snapshot in the .pvd."""
    by_time: dict[float, dict[int, str]] = {}
    for ds in ET.parse(out_dir / "snapshots.pvd").getroot().iter("DataSet"):
        by_time.setdefault(float(ds.get("timestep")), {})[int(ds.get("part"))] = str(out_dir / ds.get("file"))
    return [(t, p[0], [p[k] for k in sorted(p) if k > 0]) for t, p in sorted(by_time.items())]


def render_frames(jobs: list[tuple[str, list[str], str, float]], color: str, size: tuple[int, int], view_name: str):
    """Inside pvbatch: draws each (grains file, wall files, png, time)."""
    from paraview import simple as pv

    view = pv.CreateRenderView() if hasattr(pv, "CreateRenderView") else pv.GetActiveViewOrCreate("RenderView")
    view.ViewSize = list(size)
    view.Background = [1.0, 1.0, 1.0]
    if hasattr(view, "UseColorPaletteForBackground"):
        view.UseColorPaletteForBackground = 0
    view.OrientationAxesVisibility = 0
    grains = pv.XMLPolyDataReader(FileName=[jobs[0][0]])
    glyph = pv.Glyph(Input=grains, GlyphType="Sphere")
    glyph.ScaleArray = ["POINTS", "radius"]
    glyph.ScaleFactor = 2.0  # the sphere source has diameter 1
    glyph.GlyphMode = "All Points"
    glyph.GlyphType.ThetaResolution = 16
    glyph.GlyphType.PhiResolution = 12
    shown = pv.Show(glyph, view)
    array = ("POINTS", "velocity", "Magnitude") if color == "speed" else ("POINTS", color)
    pv.ColorBy(shown, array)
    lut = pv.GetColorTransferFunction("velocity" if color == "speed" else color)
    if color in ("mode", "group", "material") and hasattr(lut, "ApplyPreset"):
        lut.ApplyPreset("Rainbow Uniform", True)
    shown.SetScalarBarVisibility(view, True)
    bar = pv.GetScalarBar(lut, view)
    bar.Title = color
    bar.ComponentTitle = ""
    bar.TitleColor = bar.LabelColor = [0.1, 0.1, 0.1]
    walls = []
    title = pv.Text(Text="")
    tshown = pv.Show(title, view)
    tshown.Color = [0.1, 0.1, 0.1]
    tshown.FontSize = 14
    tshown.WindowLocation = "Upper Left Corner"
    first = True
    for grains_file, wall_files, png, t in jobs:
        grains.FileName = [grains_file]
        for w in walls:
            pv.Delete(w)
        walls = []
        for f in wall_files:
            r = pv.XMLPolyDataReader(FileName=[f])
            d = pv.Show(r, view)
            d.DiffuseColor = d.AmbientColor = [0.45, 0.45, 0.55]
            d.Opacity = 0.25
            d.LineWidth = 2.0
            walls.append(r)
        title.Text = f"t = {t:.4g} s"
        pv.Render(view)
        if first:
            shown.RescaleTransferFunctionToDataRange(True, False)
            bounds = grains.GetDataInformation().GetBounds()
            cam = view.GetActiveCamera()
            cx, cy, cz = [(bounds[2 * k] + bounds[2 * k + 1]) / 2 for k in range(3)]
            if view_name == "top":  # and every 2D run
                cam.SetPosition(cx, cy, cz + 1.0)
                cam.SetViewUp(0, 1, 0)
            elif view_name == "front":
                cam.SetPosition(cx, cy - 1.0, cz)
                cam.SetViewUp(0, 0, 1)
            elif view_name == "side":
                cam.SetPosition(cx + 1.0, cy, cz)
                cam.SetViewUp(0, 0, 1)
            else:
                cam.SetPosition(cx + 1.0, cy - 1.3, cz + 0.8)
                cam.SetViewUp(0, 0, 1)
            cam.SetFocalPoint(cx, cy, cz)
            view.ResetCamera()
            first = False
        pv.SaveScreenshot(png, view, ImageResolution=list(size))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out_dir", type=Path)
    ap.add_argument("--png", type=Path)
    ap.add_argument("--time", type=float)
    ap.add_argument("--frames", type=Path)
    ap.add_argument("--gif", type=Path)
    ap.add_argument("--color", default="speed", choices=FIELDS)
    ap.add_argument("--size", type=int, nargs=2, default=[900, 700], metavar=("W", "H"))
    ap.add_argument("--view", default="iso", choices=["iso", "front", "side", "top"])
    a = ap.parse_args()

    pvd = a.out_dir / "snapshots.pvd"
    if not pvd.exists():
        print(f"render.py: {pvd}: missing (run with output.snapshot_interval > 0 and output.format \"vtk\")",
              file=sys.stderr)
        return 2
    frames = frames_of(a.out_dir)
    if not frames:
        print(f"render.py: {pvd}: lists no snapshots", file=sys.stderr)
        return 2
    if a.frames or a.gif:
        outdir = a.frames or a.out_dir / "frames"
        outdir.mkdir(parents=True, exist_ok=True)
        jobs = [(g, w, str(outdir / f"frame_{k:06d}.png"), t) for k, (t, g, w) in enumerate(frames)]
    else:
        t, g, w = frames[-1] if a.time is None else min(frames, key=lambda f: abs(f[0] - a.time))
        jobs = [(g, w, str(a.png or a.out_dir / "render.png"), t)]

    if os.environ.get(INNER):  # inside pvbatch
        dim = json.loads((a.out_dir / "summary.json").read_text()).get("dimension", 3) \
            if (a.out_dir / "summary.json").exists() else 3
        render_frames(jobs, a.color, tuple(a.size), "top" if dim == 2 else a.view)
        sys.stdout.flush()
        os._exit(0)  # pvbatch 5.11 can crash tearing down its views after the pictures are written

    pvbatch = shutil.which("pvbatch")
    if not pvbatch:
        print("render.py: ParaView is not installed (no pvbatch on PATH); install Debian's paraview "
              "(tools/install-deps.sh does) or draw with tools/render_snapshot.py (matplotlib)", file=sys.stderr)
        return 3
    env = dict(os.environ, **{INNER: "1"})
    script = [str(Path(__file__).resolve())] + sys.argv[1:]
    # Debian's ParaView renders through X. With a display: offscreen through it. Without one, or if
    # that fails: on a private virtual display (a failed window start is tried again on a fresh
    # server), else under xvfb-run.
    r = None
    if os.environ.get("DISPLAY"):
        r = subprocess.run([pvbatch, "--force-offscreen-rendering"] + script, env=env, capture_output=True, text=True)
    if (r is None or r.returncode != 0) and shutil.which("Xvfb"):
        for attempt in range(3):
            with virtual_display() as display:
                if display is None:
                    r = subprocess.CompletedProcess([], 4, "", "render.py: Xvfb did not start a display")
                else:
                    r = subprocess.run([pvbatch] + script, env=dict(env, DISPLAY=display),
                                       capture_output=True, text=True)
            # Only a window that could not be made is tried again: any other failure would repeat.
            if r.returncode == 0 or attempt == 2 or (display is not None and "CreateAWindow" not in r.stderr):
                break
            time.sleep(1 + attempt)
    elif r is None or r.returncode != 0:
        if shutil.which("xvfb-run"):
            r = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1280x1024x24 -noreset", pvbatch] + script,
                               env=env, capture_output=True, text=True)
        elif r is None:
            r = subprocess.run([pvbatch, "--force-offscreen-rendering"] + script, env=env, capture_output=True,
                               text=True)
    missing = [j[2] for j in jobs if not Path(j[2]).exists()]
    if r.returncode != 0 or missing:
        # ParaView's own error lines first (its stack trace, which ends the output, does not say why).
        errors = [ln for ln in r.stderr.splitlines() if "ERR|" in ln or "Error" in ln][:5]
        print(f"render.py: pvbatch failed (status {r.returncode}):\n" + "\n".join(errors) + "\n"
              + r.stderr[-1500:], file=sys.stderr)
        return 4
    if a.gif:
        from PIL import Image
        imgs = [Image.open(j[2]).convert("P", palette=Image.ADAPTIVE) for j in jobs]
        imgs[0].save(a.gif, save_all=True, append_images=imgs[1:], duration=120, loop=0)
        print(f"render.py: {len(jobs)} frames in {outdir}, animation {a.gif}")
    elif a.frames:
        print(f"render.py: {len(jobs)} frames in {a.frames}")
    else:
        print(f"render.py: {jobs[0][2]} (t = {jobs[0][3]:.4g} s, colour: {a.color})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
