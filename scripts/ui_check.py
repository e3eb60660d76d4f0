"""Drives the Surface Map sidebar in a real Blender window and takes screenshots (a manual UI
check, not a test): the sample pair double_torus_g2 -> vase_g2 (UI_CHECK_PAIR=SOURCE,TARGET:
another pair of samples/meshes, e.g. triple_torus_g3,polycube_g3), Compute Map as the button runs
it (modal, worker thread, outputs in timer slices) while an app timer measures how often the UI
ticks, Ctrl+Z / Ctrl+Shift+Z on the outputs, then each Show button and Cut Seams.

  Xvfb :99 -screen 0 1600x1200x24 &  DISPLAY=:99 twm -f RC &   (a window manager: focus)
  with RC a file holding 'RandomPlacement' and 'UsePPosition "on"': twm's default asks the
  user to place each new window and grabs the X server meanwhile (Blender and every X client
  then hang). Its title bar pushes the status bar off the screen; 'NoTitle' in RC shows it,
  but the click on Compute Map then misses (the coordinates assume the title bar): add
  UI_CHECK_INVOKE=1
  blender -b --factory-startup --python-expr \
      "import bpy; bpy.ops.wm.save_as_mainfile(filepath='/tmp/empty.blend')"
  DISPLAY=:99 SURFMAP_PYTHONPATH=build/python blender --factory-startup \
      --window-geometry 0 0 1600 1200 /tmp/empty.blend --python scripts/ui_check.py -- --out DIR
(opening a file skips the splash screen)

Screenshots (ImageMagick's `import -window root`) go to DIR (default /tmp/surfmap_ui); the
measurements are printed as lines starting with 'UI-CHECK': one window redraw's cost before the
run, the core's stage times, every pause > 0.45 s of the 0.1 s timer with its stages, the
one-second windows with fewer than 2 ticks (from the job's start). UI_CHECK_QUICK=1: only the
panel with Cut Loops opened; UI_CHECK_INVOKE=1: Compute Map by INVOKE_DEFAULT, not a click;
UI_CHECK_RUNS=k: Compute Map k times in a row (more one-second windows; one line 'UI-CHECK
ticks per 1 s window' with their distribution over all runs; the first click after a run is
lost while Blender redraws the 3D view: repeated runs click once the view has not been drawn
for 4 s; a click still lost is repeated after 8 s).
UI_CHECK_PAIR may name mesh files by path (an open pair, e.g. two meshes written by
bench/bench_open_surfaces.py's shapes). UI_CHECK_PAIRINGS_GIVEN='1 0 2' (with UI_CHECK_QUICK): a
second screenshot with both pairings' Auto boxes unticked and these boundary loops typed in.
UI_CHECK_STAGE_SHOTS=1: a screenshot at each new stage text during the run (each is logged
either way, with the status bar's text and the sidebar's). UI_CHECK_NO_PRESHOT=1: no
screenshot before a repeated run's click; UI_CHECK_LEAVE_REGION=1: the pointer over the 3D view before it moves onto the button; UI_CHECK_CLICK=batched and
UI_CHECK_NO_SETTLE=1: the old click (sent from inside the script's callback; 3 s after the
run); UI_CHECK_EVENT_LOG=1: every event Blender hands out around each click, logged;
UI_CHECK_DEBUG_EVENTS=1: Blender's own event/handler debug output around each click.

UI_CHECK_IDLE=S: no compute; the same timer counts ticks for S seconds of a Blender that only
waits (the machine's load and llvmpipe alone), and with UI_CHECK_IDLE_REDRAW=1 the sidebar and
the status bar are changed once a second (=sidebar, =status: only that one) as Compute Map's progress does (what drawing that
progress costs without the compute), so a run's tick rate can be compared with Blender's own
under the same load.
"""
import os
import subprocess
import sys
import time

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(REPO, "addon"))
argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
OUT = argv[argv.index("--out") + 1] if "--out" in argv else "/tmp/surfmap_ui"
os.makedirs(OUT, exist_ok=True)


SOURCE, TARGET = os.environ.get("UI_CHECK_PAIR", "double_torus_g2,vase_g2").split(",")


def log(*a):
    print("UI-CHECK", *a)
    sys.stdout.flush()


def shot(name, wait=True):
    """A screenshot of the X screen. wait=False during the compute: `import` takes seconds on
    a busy machine and waiting for it blocks Blender's main thread (this script's own 3-6 s
    "UI stall" before docs/addon.md's fix: the main thread sat in waitpid)."""
    path = os.path.join(OUT, name)
    cmd = ["import", "-window", "root", path]
    if wait:
        t = time.time()
        subprocess.run(cmd, check=False)
        log(f"screenshot took {time.time() - t:.2f}s")
    else:
        STATE.setdefault("shots", []).append(subprocess.Popen(cmd))
    log("screenshot", path)


def view3d():
    win = bpy.context.window_manager.windows[0]
    for area in win.screen.areas:
        if area.type == 'VIEW_3D':
            region = next(r for r in area.regions if r.type == 'WINDOW')
            return win, area, region
    raise RuntimeError("no 3D view")


def call(op, *args, **kw):
    win, area, region = view3d()
    with bpy.context.temp_override(window=win, area=area, region=region):
        return op(*args, **kw)


def xdo(*args):
    subprocess.run(["xdotool", *args], check=False)


def redraw_all():
    """Every area redrawn, and the pointer over the sidebar (panels settle on redraws)."""
    win, area, _ = view3d()
    for a in win.screen.areas:
        a.tag_redraw()
    ui = next(r for r in area.regions if r.type == 'UI')
    xdo("mousemove", str(ui.x + ui.width // 2), str(win.height - (ui.y + ui.height // 2)))
    log("pointer parked at", pointer())


def focus_blender():
    """Keyboard focus on Blender's window (Xvfb runs no window manager to give it)."""
    ids = subprocess.run(["xdotool", "search", "--name", "Blender"], capture_output=True,
                         text=True).stdout.split()
    for wid in ids:
        xdo("windowfocus", wid)


def setup():
    import addon_utils
    addon_utils.enable("surface_map", default_set=True, handle_error=None)
    from surface_map import native
    sm = native.load()
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob, do_unlink=True)
    import numpy as np
    obs = []
    for name, x in ((SOURCE, -1.6), (TARGET, 1.6)):
        # a path (open meshes generated elsewhere) or the name of a sample
        path = name if os.sep in name else os.path.join(REPO, "samples", "meshes", name + ".obj")
        name = os.path.splitext(os.path.basename(name))[0]
        V, polys = sm.read_polygon_soup(path)
        V = np.asarray(V, dtype=float)
        V = (V - V.mean(axis=0)) / np.ptp(V, axis=0).max() * 2.4
        me = bpy.data.meshes.new(name)
        me.from_pydata(V.tolist(), [], [list(p) for p in polys])
        me.polygons.foreach_set("use_smooth", [True] * len(me.polygons))
        me.update()
        ob = bpy.data.objects.new(name, me)
        ob.location.x = x
        if "_torus_g" in name:   # the n-hole tori lie flat: stood up facing the view
            ob.rotation_euler.x = 1.5708
        bpy.context.scene.collection.objects.link(ob)
        obs.append(ob)
    for ob in obs:
        ob.select_set(True)
    bpy.context.view_layer.objects.active = obs[1]
    call(bpy.ops.ed.undo_push, message="ui_check: the sample pair")   # Ctrl+Z stops here
    if os.environ.get("UI_CHECK_VIEWPORT_AA"):
        # the viewport's progressive anti-aliasing redraws the view several times after each
        # change; with software OpenGL on a busy machine each redraw takes seconds
        bpy.context.preferences.system.viewport_aa = os.environ["UI_CHECK_VIEWPORT_AA"]
        log("viewport anti-aliasing:", bpy.context.preferences.system.viewport_aa)
    win, area, region = view3d()
    space = area.spaces.active
    space.show_region_ui = True
    space.overlay.show_floor = False
    ui = next(r for r in area.regions if r.type == 'UI')
    log("sidebar width px", ui.width, "window", win.width, win.height)


def open_tab():
    """Clicks the sidebar's 'Surface Map' tab (Blender 3.4 has no Python API for the tab):
    the tabs are a column at the sidebar's right edge, ours is the last one."""
    win, area, _ = view3d()
    ui = next(r for r in area.regions if r.type == 'UI')
    x = ui.x + ui.width - 10
    y_top = win.height - (ui.y + ui.height)
    focus_blender()
    xdo("mousemove", str(x), str(y_top + 195))
    time.sleep(0.3)
    xdo("mousemove", str(x + 1), str(y_top + 196))
    time.sleep(0.3)
    xdo("mousedown", "1")
    time.sleep(0.15)
    xdo("mouseup", "1")
    log("clicked the sidebar tab at", x, y_top + 196)
    call(bpy.ops.view3d.view_axis, type='FRONT')
    call(bpy.ops.view3d.view_selected)


def measure_redraws():
    """What redraws cost Blender now (software OpenGL, this load): the whole window, and the
    sidebar region alone with the window composited and swapped (what one progress update
    costs). No timer can tick while Blender draws, so these bound the UI's pauses from below."""
    t = time.time()
    call(bpy.ops.wm.redraw_timer, type='DRAW_WIN_SWAP', iterations=3)
    STATE["window_redraw"] = (time.time() - t) / 3
    win, area, _ = view3d()
    ui = next(r for r in area.regions if r.type == 'UI')
    t = time.time()
    with bpy.context.temp_override(window=win, area=area, region=ui):
        bpy.ops.wm.redraw_timer(type='DRAW_SWAP', iterations=3)
    STATE["sidebar_redraw"] = (time.time() - t) / 3
    # (type='DRAW', without the swap, crashes Blender 3.4 in a window: not measured)
    log(f"one window redraw (DRAW_WIN_SWAP) takes {STATE['window_redraw']:.3f}s, the sidebar "
        f"with the window's swap (DRAW_SWAP) {STATE['sidebar_redraw']:.3f}s, load average {' '.join(f'{x:.1f}' for x in os.getloadavg())}")


def click_compute():
    """A click on the panel's Compute Map button, as a user does: the pointer moved onto it in
    two steps (Blender highlights a button on a motion event over it), pressed and released.

    The xdotool sequence runs in a background process while this timer callback returns, so
    Blender's event loop takes each motion, the press and the release as they come, as with a
    user's hand (UI_CHECK_CLICK=batched: the old way, the sequence with its sleeps run inside
    this callback, Blender blocked meanwhile). Either way, when Blender's main thread is busy
    (a 3D view draw: view_settling) it reads the whole click in one batch with its motions
    merged into one; if the pointer was parked over another button (the sidebar's middle,
    redraw_all(), is on the pairings list after a run) that one motion only un-highlights it
    and the press finds no highlighted button: the click is lost (docs/addon.md, "The lost
    first click after a run")."""
    win, area, _ = view3d()
    ui = next(r for r in area.regions if r.type == 'UI')
    x, y = ui.x + ui.width // 2, win.height - (ui.y + ui.height) + COMPUTE_BUTTON_Y
    focus_blender()
    log("pointer before the click at", pointer())
    moves = []
    if os.environ.get("UI_CHECK_LEAVE_REGION"):   # the pointer over the 3D view first
        moves.append((area.x + area.width // 3, y, 0.5))
    moves += [(x - 20, y - 2, 0.3), (x, y, 0.3)]
    if os.environ.get("UI_CHECK_CLICK") == "batched":
        for mx, my, pause in moves:
            xdo("mousemove", str(mx), str(my))
            time.sleep(pause)
        xdo("mousedown", "1")
        time.sleep(0.15)
        xdo("mouseup", "1")
    else:
        stamp = "echo UI-CHECK xdotool $(date +%s.%N)"
        script = "".join(f"xdotool mousemove {mx} {my}; {stamp} moved {mx} {my}; sleep {pause}; "
                         for mx, my, pause in moves)
        script += (f"xdotool mousedown 1; {stamp} pressed; sleep 0.15; xdotool mouseup 1; "
                   f"{stamp} released")
        STATE.setdefault("clickers", []).append(subprocess.Popen(["sh", "-c", script]))
    STATE["t_click"] = time.time()
    STATE["clicks"] = STATE.get("clicks", 0) + 1
    log("clicked Compute Map at", x, y, "(%s)" % (os.environ.get("UI_CHECK_CLICK") or "live"))


SETTLE = 4.0   # seconds without a 3D view draw before a repeated run's click


def view_settling(kinds=("draws",)):
    """Seconds to wait before a repeated run's click (None: click now): until the 3D view has not
    been drawn for SETTLE s, as an artist clicks once the result is on screen (given up after
    120 polls, 60 s of waiting seen by this timer: a redraw that never ends is then clicked
    through and logged). After a run Blender redraws the view once per sample of its
    progressive viewport anti-aliasing (Preferences > Viewport > Anti-Aliasing, 8 samples by
    default), each one 2-3.5 s of the main thread with software OpenGL at load 15; a click
    made meanwhile reaches Blender as one batch of events, its motions merged, and is lost
    (click_compute). UI_CHECK_NO_SETTLE=1 clicks 3 s after the run, as before. kinds: which
    draw times count (STATE["draws"]: the 3D view, "ui_draws": the sidebar; the screenshots
    wait for both: a shot taken while the sidebar's panels still slide into place shows the
    Result panel over the Outputs buttons)."""
    now = time.time()
    t0 = STATE.setdefault("t_settle0", now)
    STATE["settle_polls"] = STATE.get("settle_polls", 0) + 1
    last = max([x for kind in kinds for x in STATE.get(kind, [])] + [0.0])
    if now - last < SETTLE and STATE["settle_polls"] <= 120:
        return 0.5
    done = STATE.get("t_done") or t0
    log(f"the view {'settled' if now - last >= SETTLE else 'still drawing (gave up)'}: "
        f"{sum(1 for x in STATE.get('draws', []) if x > done)} draws since the run, the last "
        f"{now - last:.1f}s ago; waited {now - t0:.1f}s")
    del STATE["t_settle0"], STATE["settle_polls"]
    return None


def pointer():
    """xdotool getmouselocation: 'x:.. y:..'."""
    out = subprocess.run(["xdotool", "getmouselocation"], capture_output=True, text=True).stdout
    return " ".join(out.split()[:2])


class UICHECK_OT_event_log(bpy.types.Operator):
    """UI_CHECK_EVENT_LOG=1: logs every mouse event Blender's window manager hands out (a
    window-level modal handler that passes everything through) from just before a click until
    the job starts: which motions Blender saw, merged or not, and when."""
    bl_idname = "wm.ui_check_event_log"
    bl_label = "ui_check event log"

    def invoke(self, context, event):
        context.window_manager.modal_handler_add(self)
        return {'RUNNING_MODAL'}

    def modal(self, context, event):
        if STATE.get("stop_event_log"):
            return {'FINISHED', 'PASS_THROUGH'}
        if not event.type.startswith('TIMER'):
            log(f"event {event.type} {event.value} at {event.mouse_x},{event.mouse_y} "
                f"{time.time():.3f}")
        return {'PASS_THROUGH'}


def idle_progress():
    """UI_CHECK_IDLE_REDRAW: what Compute Map's progress display does once a second (a new
    status bar text, the sidebar region tagged), without any compute."""
    STATE["idle_n"] = STATE.get("idle_n", 0) + 1
    what = os.environ.get("UI_CHECK_IDLE_REDRAW")
    if what in ("1", "status"):
        ws = bpy.context.window_manager.windows[0].workspace
        ws.status_text_set(f"Surface Map: idle check ({STATE['idle_n']}s) — Esc to cancel")
    if what in ("1", "sidebar"):
        _, area, _ = view3d()
        for r in area.regions:
            if r.type == 'UI':
                r.tag_redraw()
    return 1.0


# Compute Map's button, pixels below the sidebar's top at the default layout (Cut Loops closed)
COMPUTE_BUTTON_Y = 345
CUT_LOOPS_HEADER_Y = 153
STATE = {"step": 0, "ticks": [], "t_start": None, "progress_shot": False}


def record_progress_calls():
    """Wraps MapJob._progress (the core's callback, on the worker thread) to log each stage's
    time, so the UI's pauses can be placed among the core's stages."""
    from surface_map import map_job
    original = map_job.MapJob._progress

    def logged(job, stage, fraction, *extra):
        STATE.setdefault("progress_calls", []).append((time.time(), str(stage)))
        return original(job, stage, fraction, *extra)
    map_job.MapJob._progress = logged
    # the moment the modal operator sees the job done (then it writes the outputs and the
    # 3D view redraws with them: the result appearing, after the compute)
    from surface_map import ops_map
    cleanup = ops_map.SURFMAP_OT_compute_map._cleanup

    def logged_cleanup(op, context):
        STATE["t_done"] = time.time()
        return cleanup(op, context)
    ops_map.SURFMAP_OT_compute_map._cleanup = logged_cleanup
    invoke = ops_map.SURFMAP_OT_compute_map.invoke

    def logged_invoke(op, context, event):
        r = invoke(op, context, event)
        log(f"Compute Map invoked ({event.type} {event.value}) -> {r}")
        return r
    ops_map.SURFMAP_OT_compute_map.invoke = logged_invoke


def count_draw():
    STATE.setdefault("draws", []).append(time.time())


def count_ui_draw():
    STATE.setdefault("ui_draws", []).append(time.time())


def ticker():
    from surface_map import map_job
    job = map_job.ACTIVE.get("job")
    STATE["ticks"].append(time.time())
    STATE.setdefault("stages", []).append(job.stage if job is not None else "-")
    if job is not None and job._slices is not None:
        STATE["slices"] = job._slices.slice_times
    if job is not None:
        STATE["tick_work"] = getattr(job, "tick_work", [])
    return 0.1


def window_rates(ticks, t0, t1):
    """Ticks in each one-second window [s, s + 1) for s = t0, t0 + 0.5, ... up to t1 - 1."""
    return [sum(1 for x in ticks if s <= x < s + 1.0) for s in
            [t0 + 0.5 * k for k in range(int((t1 - t0 - 1.0) / 0.5) + 1)]] if t1 - t0 >= 1.0 else []


def rate_distribution(rates):
    """'min m, windows < 2: a of n, histogram {ticks: windows}' of window_rates' counts."""
    if not rates:
        return "no whole one-second window"
    hist = {r: rates.count(r) for r in sorted(set(rates))}
    return (f"min {min(rates)}, median {sorted(rates)[len(rates) // 2]}, windows < 2: "
            f"{sum(1 for r in rates if r < 2)} of {len(rates)}, histogram {hist}")


def tick_report():
    from surface_map import map_job  # noqa: F401
    t = STATE["ticks"]
    t0, t_end = STATE["t_start"], STATE["t_end"]
    # (from the job's start: before it, this script's own click, with its sleeps and xdotool
    # calls, holds the main thread; to the moment the operator saw the job done: then it
    # writes the outputs and the 3D view redraws with them)
    t0 = max(t0, STATE.get("job_t0") or t0)
    t1 = min(t_end, STATE.get("t_done") or t_end)
    inside = [x for x in t if t0 <= x <= t1]
    gaps = [b - a for a, b in zip(inside, inside[1:])]
    worst_rate = None
    rates = window_rates(inside, t0, t1)
    STATE.setdefault("all_rates", []).extend(rates)
    if rates:
        worst_rate = min(rates)
        log(f"  1 s windows (every 0.5 s from the job's start) with fewer than 2 ticks: "
            f"{sum(1 for r in rates if r < 2)} of {len(rates)}, starting at (s after the "
            f"start) {[0.5 * k for k, r in enumerate(rates) if r < 2]}")
    if inside:
        log(f"  last tick {t1 - inside[-1]:.2f}s before the job was seen done")
    st = STATE.get("stages", [])
    for k in range(1, len(t)):
        if t0 <= t[k] <= t1 and t[k] - t[k - 1] > 0.45:
            log(f"  gap {t[k] - t[k - 1]:.2f}s between stages '{st[k - 1]}' and '{st[k]}' "
                f"({t[k - 1] - t0:.2f}s to {t[k] - t0:.2f}s after the job's start)")
    last = None
    for when, stage in STATE.get("progress_calls", []):
        if stage != last and when >= t0 - 1.0:   # (this run's stages only)
            log(f"  core stage '{stage}' reported at {when - t0:.2f}s (abs {when:.3f})")
            last = stage
    dr = [x for x in STATE.get("draws", []) if t0 <= x <= t1]
    log("  3D view draws during the compute:", len(dr), "at (s after start)",
        [round(x - t0, 1) for x in dr][:40])
    ud = [x for x in STATE.get("ui_draws", []) if t0 <= x <= t1]
    log("  sidebar draws during the compute:", len(ud), "at", [round(x - t0, 1) for x in ud][:40])
    tw = STATE.get("tick_work", [])
    if len(tw) > 1:
        log("  modal ticks:", len(tw), "longest work in one tick %.3fs" % max(w for _, w in tw),
            "longest gap between ticks %.3fs" % max(b[0] - a[0] for a, b in zip(tw, tw[1:])))
    slow = sorted(STATE.get("slices", []), key=lambda x: -x[1])[:5]
    log("  slowest output slices:", [(a, round(b, 3)) for a, b in slow])
    if "window_redraw" in STATE:
        log(f"  pauses longer than 1.5 window redraws ({1.5 * STATE['window_redraw']:.2f}s): "
            f"{sum(1 for g in gaps if g > 1.5 * STATE['window_redraw'])}")
    log(f"compute wall {t1 - t0:.1f}s, timer ticks {len(inside)}, longest gap "
        f"{max(gaps) if gaps else float('nan'):.3f}s, lowest ticks in any 1 s window "
        f"{worst_rate}")


def outputs_gone():
    t = bpy.data.objects.get(TARGET)
    return t is not None and t.data.attributes.get("surfmap_map_face") is None \
        and t.data.color_attributes.get("surfmap dilatation") is None \
        and not any(u.name.startswith("surfmap ") for u in t.data.uv_layers)


SHOT_STEPS = {5, 8, 10, 11, 12, 13, 14, 15, 16, 17}   # steps that begin with a screenshot


def step():
    s = STATE["step"]
    if s in SHOT_STEPS and "draws" in STATE and not os.environ.get("UI_CHECK_NO_SETTLE"):
        wait = view_settling(("draws", "ui_draws"))
        if wait:
            return wait
    if s == 0:
        setup()
        STATE["step"] = 1
        return 1.0
    settings = bpy.context.scene.surfmap
    from surface_map import map_job
    if s == 1:
        open_tab()
        if os.environ.get("UI_CHECK_QUICK"):   # the panel with Cut Loops opened, one shot
            STATE["step"] = 98
            return 3.0
    elif s == 2:
        if not STATE.get("tab_again"):      # (the first click may come before focus)
            STATE["tab_again"] = True
            open_tab()
            return 3.0
        if not STATE.get("measuring"):
            STATE["measuring"] = True
            shot("01_panel_before.png")
            measure_redraws()
            bpy.app.timers.register(ticker, first_interval=0.1)
            record_progress_calls()
            bpy.types.SpaceView3D.draw_handler_add(count_draw, (), 'WINDOW', 'POST_PIXEL')
            bpy.types.SpaceView3D.draw_handler_add(count_ui_draw, (), 'UI', 'POST_PIXEL')
        if STATE.get("runs") and not (os.environ.get("UI_CHECK_NO_SETTLE")
                                      or os.environ.get("UI_CHECK_INVOKE")):
            wait = view_settling()
            if wait:
                return wait
        STATE["t_start"] = time.time()
        STATE["job_t0"], STATE["seen_job"], STATE["clicks"] = None, False, 0
        if os.environ.get("UI_CHECK_IDLE"):
            STATE["step"] = 50
            if os.environ.get("UI_CHECK_IDLE_REDRAW"):
                bpy.app.timers.register(idle_progress, first_interval=1.0)
            log(f"idle for {os.environ['UI_CHECK_IDLE']}s, sidebar and status bar changed once "
                f"a second: {bool(os.environ.get('UI_CHECK_IDLE_REDRAW'))}")
            return float(os.environ["UI_CHECK_IDLE"])
        log(f"compute starts at abs {STATE['t_start']:.3f}")
        if os.environ.get("UI_CHECK_INVOKE"):
            r = call(bpy.ops.surfmap.compute_map, 'INVOKE_DEFAULT')
            log("compute_map invoke ->", r)
        else:   # a click on the panel's Compute Map button, as a user does
            if STATE.get("runs") and STATE.get("t_done"):   # has the sidebar settled?
                since = STATE["t_done"]
                log("since the last job was seen done (s): sidebar draws",
                    [round(x - since, 2) for x in STATE.get("ui_draws", []) if x > since],
                    "3D view draws", [round(x - since, 2) for x in STATE.get("draws", [])
                                      if x > since], "now", round(time.time() - since, 2))
            if STATE.get("runs") and not os.environ.get("UI_CHECK_NO_PRESHOT"):
                shot(f"01_panel_before_run{STATE['runs'] + 1}.png")
                log("Compute Map's poll before this run:", call(bpy.ops.surfmap.compute_map.poll))
            if os.environ.get("UI_CHECK_DEBUG_EVENTS"):
                bpy.app.debug_events = bpy.app.debug_handlers = True
                log("debug events on at abs %.3f" % time.time())
            if os.environ.get("UI_CHECK_EVENT_LOG"):
                STATE["stop_event_log"] = False
                call(bpy.ops.wm.ui_check_event_log, 'INVOKE_DEFAULT')
            click_compute()

    elif s == 3:
        job = map_job.ACTIVE.get("job")
        if job is None and not STATE.get("seen_job") and time.time() - STATE["t_start"] < 30:
            if time.time() - STATE["t_click"] > 8 and STATE["clicks"] < 3:
                # on a loaded machine a click is sometimes lost (seen 3 times at load 13-15)
                log("no job 8 s after the click: clicking again; timer ticks around the click "
                    "(s after it):", [round(x - STATE["t_click"], 2) for x in STATE["ticks"]
                                      if -1 < x - STATE["t_click"] < 4],
                    "3D view draws", [round(x - STATE["t_click"], 2) for x in STATE.get("draws", [])
                                      if -3 < x - STATE["t_click"] < 4],
                    "sidebar draws", [round(x - STATE["t_click"], 2) for x in
                                      STATE.get("ui_draws", []) if -3 < x - STATE["t_click"] < 4])
                shot(f"lost_click_{STATE.get('runs', 0) + 1}_{STATE['clicks']}.png")
                STATE["t_start"] = time.time()
                click_compute()
            return 0.2     # the click is not processed yet
        if job is not None:
            if bpy.app.debug_events:
                bpy.app.debug_events = bpy.app.debug_handlers = False
            STATE["stop_event_log"] = True
            if not STATE["seen_job"] and not os.environ.get("UI_CHECK_INVOKE"):
                STATE.setdefault("clicks_needed", []).append(STATE["clicks"])
                log(f"the job started after {STATE['clicks']} click(s)")
            STATE["seen_job"] = True
            STATE["job_t0"] = job.t0
            if job.fraction > 0.3 and not STATE["progress_shot"]:
                shot("02_progress.png", wait=False)
                STATE["progress_shot"] = True
            text = job.stage_text()
            if text != STATE.get("stage_text"):   # every stage as the status bar names it
                STATE["stage_text"] = text
                log(f"stage at {time.time() - STATE['t_start']:.1f}s: {job.status_text()!r}, "
                    f"sidebar {job.stage_text(short=True)!r}")
                if os.environ.get("UI_CHECK_STAGE_SHOTS"):
                    STATE["stage_shots"] = STATE.get("stage_shots", 0) + 1
                    shot(f"02_stage_{STATE['stage_shots']:02d}.png", wait=False)
            return 0.2     # stay on this step
        STATE["t_end"] = time.time()
        tick_report()
        log("summary:", [(r.name, r.value) for r in settings.summary_rows])
        log("max tick gap seen by the operator", settings.max_tick_gap)
        STATE["runs"] = STATE.get("runs", 0) + 1
        if STATE["runs"] < int(os.environ.get("UI_CHECK_RUNS", "1")):
            STATE["step"] = 2       # Compute Map again (its outputs replace the last run's)
            redraw_all()            # (a button drawn disabled was seen once: redrawn first)
            return 3.0
        needed = STATE.get("clicks_needed", [])
        log(f"runs started by their first click: {needed.count(1)} of {len(needed)} "
            f"(clicks per run {needed})")
        log(f"ticks per 1 s window over {STATE['runs']} run(s): "
            f"{rate_distribution(STATE['all_rates'])}, load average "
            f"{' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    elif s == 4:
        if STATE.get("t_done"):   # the outputs written and the 3D view redrawn with them
            after = [x for x in STATE["ticks"] if x > STATE["t_done"]]
            log(f"  the first tick after the job was seen done came "
                f"{after[0] - STATE['t_done'] if after else float('nan'):.2f}s later (writing "
                f"the outputs, the 3D view redrawn with them)")
        open_tab()
    elif s == 5:
        shot("03_result_panel.png")
    elif s == 6:
        win, area, region = view3d()
        cx, cy = area.x + area.width // 3, win.height - (area.y + area.height // 2)
        xdo("mousemove", str(cx), str(cy))
        focus_blender()
        for _ in range(STATE.get("runs", 1)):   # (each run is one undo step)
            xdo("key", "ctrl+z")
    elif s == 7:
        log("after Ctrl+Z (xdotool) the outputs are gone:", outputs_gone())
    elif s == 8:
        shot("04_after_undo.png")
        focus_blender()
        for _ in range(STATE.get("runs", 1)):
            xdo("key", "ctrl+shift+z")
    elif s == 9:
        log("after Ctrl+Shift+Z the outputs are there:", not outputs_gone())
        r = call(bpy.ops.surfmap.show_output, what='COLOURS',
                 attribute=map_job.DILATATION_COLOURS)
        log("show D' ->", r)
    elif s == 10:
        shot("05_colours_dilatation.png")
        call(bpy.ops.surfmap.show_output, what='COLOURS', attribute=map_job.CONFORMAL_COLOURS)
    elif s == 11:
        shot("06_colours_area.png")
        call(bpy.ops.surfmap.show_output, what='TEXTURE')
    elif s == 12:
        shot("07_texture.png")
        call(bpy.ops.surfmap.show_output, what='MORPH')
    elif s == 13:
        shot("08_morph_half.png")
        call(bpy.ops.surfmap.show_output, what='BACK')
    elif s == 14:
        shot("09_back.png")
        call(bpy.ops.surfmap.show_cut_loops)
    elif s == 15:
        shot("10_cut_loops.png")
        call(bpy.ops.surfmap.show_output, what='MORPH')
        src = bpy.data.objects.get(SOURCE)
        src.data.shape_keys.key_blocks[f"surfmap to {TARGET}"].value = 1.0
    elif s == 16:
        shot("11_loops_follow_morph.png")
        src = bpy.data.objects.get(SOURCE)
        src.data.shape_keys.key_blocks[f"surfmap to {TARGET}"].value = 0.0
        call(bpy.ops.surfmap.show_output, what='TEXTURE')
        t = time.time()
        r = call(bpy.ops.surfmap.cut_along_seams)
        log("cut along seams ->", r, f"{time.time() - t:.1f}s")
        cut = bpy.data.objects.get(f"{TARGET} cut along seams")
        target = bpy.data.objects.get(TARGET)
        if cut is not None:     # the copy shows the texture the Texture button put on the target
            cut.data.materials.clear()
            for slot in target.material_slots:
                cut.data.materials.append(slot.material)
            target.hide_set(True)
    elif s == 17:
        shot("12_cut_along_seams.png")
    elif s == 50:   # UI_CHECK_IDLE: the end of the idle stretch
        if bpy.app.timers.is_registered(idle_progress):
            bpy.app.timers.unregister(idle_progress)
        t0, t1 = STATE["t_start"], time.time()
        inside = [x for x in STATE["ticks"] if t0 <= x <= t1]
        rates = window_rates(inside, t0, t1)
        gaps = [b - a for a, b in zip(inside, inside[1:])]
        dr = [x for x in STATE.get("draws", []) if t0 <= x <= t1]
        ud = [x for x in STATE.get("ui_draws", []) if t0 <= x <= t1]
        log(f"idle {t1 - t0:.1f}s: {len(inside)} ticks, longest gap "
            f"{max(gaps) if gaps else float('nan'):.3f}s, 3D view draws {len(dr)}, sidebar "
            f"draws {len(ud)}")
        log(f"ticks per 1 s window (idle): {rate_distribution(rates)}, load average "
            f"{' '.join(f'{x:.1f}' for x in os.getloadavg())}")
        STATE["step"] = 100
        return 0.1
    elif s == 98:
        win, area, _ = view3d()
        ui = next(r for r in area.regions if r.type == 'UI')
        y = win.height - (ui.y + ui.height) + CUT_LOOPS_HEADER_Y
        xdo("mousemove", str(ui.x + ui.width // 2), str(y))
        time.sleep(0.2)
        xdo("click", "1")
        log("clicked the Cut Loops header at", ui.x + ui.width // 2, y)
    elif s == 99:
        shot("00_quick.png")
        if os.environ.get("UI_CHECK_PAIRINGS_GIVEN"):   # the Auto boxes unticked: the fields beside
            settings.homotopy_auto = False               # them, with a pairing and loops typed in
            settings.boundary_pairing = os.environ["UI_CHECK_PAIRINGS_GIVEN"]
            redraw_all()
            STATE["step"] = 110
            return 3.0
        STATE["step"] = 100
        return 0.1
    elif s == 110:
        shot("00_quick_given.png")
        STATE["step"] = 100
        return 0.1
    else:
        bpy.app.timers.unregister(ticker) if bpy.app.timers.is_registered(ticker) else None
        for p in STATE.get("shots", []) + STATE.get("clickers", []):
            p.wait(timeout=60)
        log("done")
        call(bpy.ops.wm.quit_blender)
        return None
    STATE["step"] = s + 1
    if s != 2:   # (not after the Compute click: a redraw of every area is no part of the run)
        redraw_all()
    return 4.0


def guarded_step():
    try:
        return step()
    except Exception:
        import traceback
        traceback.print_exc()
        log("FAILED at step", STATE["step"])
        call(bpy.ops.wm.quit_blender)
        return None


bpy.utils.register_class(UICHECK_OT_event_log)
bpy.app.timers.register(guarded_step, first_interval=2.0)
