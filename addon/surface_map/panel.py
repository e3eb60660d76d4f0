"""The 'Surface Map' sidebar of the 3D view (N-panel, tab 'Surface Map'): a main panel (module,
selection, progress) with the sub-panels Cut Loops, Map, Outputs and Result, the way Blender's
own panels nest, with labels short enough for the default sidebar width."""
import functools
import math

import bpy

from . import batch_operators, map_job, native
from .properties import _wrap, extra_module_dirs
from .side import describe_counts, mesh_topology

WRAP = 34   # characters per label line at the default sidebar width


def energy_text(c):
    """A candidate's energy for the list: '12.34', '~12.3 est.' or '—'."""
    if c.solved:
        return f"{c.energy:.5g}"
    if c.estimated:
        return f"~{c.energy:.4g} est."
    return "—"


def sorted_candidates(candidates):
    """Indices into `candidates` by energy (solved or estimated), the ones without last."""
    def key(i):
        c = candidates[i]
        held = c.landmark_energy
        e = held if held == held else (c.energy if (c.solved or c.estimated) else math.inf)
        return (e, i)
    return sorted(range(len(candidates)), key=key)


class SURFMAP_UL_candidates(bpy.types.UIList):
    """The handle pairings of the last run, by energy; the one the map uses is ticked."""
    bl_idname = "SURFMAP_UL_candidates"

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname,
                  index=0, flt_flag=0):
        chosen = item.index == data.chosen_candidate
        row = layout.row(align=True)
        row.label(text=f"#{item.index}", icon='CHECKMARK' if chosen else 'BLANK1')
        text = energy_text(item)
        if item.landmark_energy == item.landmark_energy:   # not nan: ranked with landmarks
            text += f" lm {item.landmark_energy:.4g}"
        sub = row.row()
        sub.alignment = 'RIGHT'
        sub.label(text=text)

    def filter_items(self, context, data, propname):
        items = getattr(data, propname)
        order = sorted_candidates(items)
        new_order = [0] * len(items)
        for pos, i in enumerate(order):
            new_order[i] = pos
        return [], new_order


def computing():
    """True while Compute Map runs: the sub-panels are then hidden, the main panel shows the
    progress bar alone. Their buttons take no clicks meanwhile (the modal operator holds the
    events), and every progress update redraws the whole sidebar: with software OpenGL its
    widgets are about half of what one update costs Blender's main thread (docs/addon.md,
    "UI ticks during the compute")."""
    return map_job.ACTIVE.get("job") is not None


class _SubPanel:
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Surface Map"
    bl_parent_id = "SURFMAP_PT_main"

    @classmethod
    def poll(cls, context):
        return not computing()


def _lines(layout, text, limit, icon='NONE'):
    for i, line in enumerate(_wrap(text, WRAP)[:limit]):
        layout.label(text=line, icon=icon if i == 0 else 'BLANK1' if icon != 'NONE' else 'NONE')


class SURFMAP_PT_main(bpy.types.Panel):
    bl_idname = "SURFMAP_PT_main"
    bl_label = "Surface Map"
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Surface Map"

    def draw(self, context):
        layout = self.layout
        mod = native.load(extra_dirs=extra_module_dirs(context))
        if mod is not None:
            layout.label(text="Native module: loaded", icon='CHECKMARK')
        else:
            box = layout.box()
            box.label(text="Native module: missing", icon='ERROR')
            for line in _wrap(native.error(), WRAP)[:8]:
                box.label(text=line)
        sel = [o for o in context.selected_objects if o.type == 'MESH']
        act = context.active_object
        col = layout.column(align=True)
        if len(sel) == 2 and act in sel:
            src = sel[0] if sel[1] == act else sel[1]
            col.label(text=f"Source: {src.name}", icon='MESH_DATA')
            col.label(text=f"Target: {act.name}", icon='MESH_DATA')
            draw_pair_topology(col, topology(src), topology(act), getattr(context, "region", None))
        elif len(sel) == 1:
            col.label(text=f"Object: {sel[0].name}", icon='MESH_DATA')
            col.label(text=describe_counts(*topology(sel[0])).capitalize(), icon='BLANK1')
        else:
            col.label(text="Select 2 meshes", icon='INFO')
            col.label(text="(the active one is the target)", icon='BLANK1')
        draw_progress(layout, context.scene.surfmap)


_TOPOLOGY = {}


def topology(ob):
    """(genus, boundary loops) of the mesh Compute Map reads (the evaluated one when the object
    has modifiers shown in the viewport, as blender_io.read_object_mesh), cached on its counts:
    the panel draws on every redraw, and the add-on maps in Object Mode only."""
    me = ob.data
    if any(m.show_viewport for m in ob.modifiers):
        me = ob.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    key = (ob.name_full, me.name_full, len(me.vertices), len(me.edges), len(me.polygons),
           len(me.loops))
    if key not in _TOPOLOGY:
        import numpy as np
        ev = np.empty(2 * len(me.edges), dtype=np.int32)
        me.edges.foreach_get("vertices", ev)
        le = np.empty(len(me.loops), dtype=np.int32)
        me.loops.foreach_get("edge_index", le)
        if len(_TOPOLOGY) > 64:
            _TOPOLOGY.clear()
        _TOPOLOGY[key] = mesh_topology(len(me.vertices), len(me.polygons), ev, le)
    return _TOPOLOGY[key]


def draw_pair_topology(col, source, target, region=None):
    """One line under the names: 'Both closed, genus 2' or 'Both genus 0, 1 boundary loop';
    a pair of different topology cannot be mapped, and the panel says so before Compute Map
    refuses it (wrapped by the labels' pixel width: by characters, 34 a line, the sidebar cut
    'Different topology: sourc…' at its default width)."""
    if source == target and source[0] is not None:
        col.label(text="Both " + describe_counts(*source), icon='BLANK1')
        return
    text = (f"Different topology: source {describe_counts(*source)}; target "
            f"{describe_counts(*target)}")
    width = label_width(region) + MAIN_PANEL_EXTRA
    for i, line in enumerate(picked_lines(text, width, *label_font())):
        col.label(text=line, icon='ERROR' if i == 0 else 'BLANK1')


def pair_is_closed(context):
    """True when every selected mesh is closed (the Boundary row is then left out)."""
    sel = [o for o in context.selected_objects if o.type == 'MESH']
    return bool(sel) and all(genus is not None and loops == 0 for genus, loops in map(topology, sel))


def draw_progress(layout, settings):
    """The running job's progress bar and stage (nothing when idle)."""
    if not computing():
        return
    col = layout.column(align=True)
    col.label(text=settings.progress_stage or "Working", icon='SORTTIME')
    if settings.progress_run:   # (the other runs, a retry: not the main run started over)
        col.label(text=settings.progress_run, icon='BLANK1')
    col.prop(settings, "progress", text="", slider=True)
    col.label(text="Esc cancels", icon='BLANK1')


class SURFMAP_PT_loops(_SubPanel, bpy.types.Panel):
    bl_idname = "SURFMAP_PT_loops"
    bl_label = "Cut Loops"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        settings = context.scene.surfmap
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        col = layout.column(align=True)
        col.label(text="Base vertex (-1: automatic)")
        col.prop(settings, "source_base_vertex", text="Source")
        col.prop(settings, "target_base_vertex", text="Target")
        col.prop(settings, "loop_bevel")
        col.prop(settings, "mark_seams")
        layout.operator("surfmap.show_cut_loops", icon='MOD_CURVE')
        if settings.status:
            _lines(layout.column(align=True), settings.status, 6)


class SURFMAP_PT_map(_SubPanel, bpy.types.Panel):
    bl_idname = "SURFMAP_PT_map"
    bl_label = "Map"

    def draw(self, context):
        draw_map(self.layout, context.scene.surfmap, getattr(context, "region", None),
                 boundary=not pair_is_closed(context))


def draw_map(layout, settings, region=None, boundary=True):
    """The map's options, its button, and the pairings of the last run."""
    layout.use_property_split = True
    layout.use_property_decorate = False
    col = layout.column(align=True)
    # Automatic (the lowest energy) is a check box, not the number -1; the number beside it
    # only when unticked.
    row = col.row(heading="Pairing", align=True)
    row.prop(settings, "homotopy_auto")
    if not settings.homotopy_auto:
        row.prop(settings, "homotopy", text="")
    col.prop(settings, "landmark_mode")
    if settings.landmark_status:
        _lines(col, settings.landmark_status, 4, icon='PINNED')
    col.prop(settings, "method")
    col.prop(settings, "source_weights")
    col.prop(settings, "tolerance_text")
    if boundary:   # (left out when the selected meshes are all closed)
        row = col.row(heading="Boundary", align=True)   # ("Boundary Loops" is cut)
        row.prop(settings, "boundary_pairing_auto")
        if not settings.boundary_pairing_auto:
            row.prop(settings, "boundary_pairing", text="")
    row = layout.row()
    row.scale_y = 1.4
    row.operator("surfmap.compute_map", icon='PLAY')
    if len(settings.candidates):
        layout.label(text="Handle pairings (energy):")
        layout.template_list("SURFMAP_UL_candidates", "", settings, "candidates", settings,
                             "candidate_index", rows=3, maxrows=5)
        layout.operator("surfmap.solve_candidate", icon='FILE_REFRESH')
        # What the picked row is (the rows show only '#k' and the energy), under the button
        # so that picking a row does not move the button.
        picked = picked_description(settings)
        if picked:
            col = layout.column(align=True)
            for i, line in enumerate(picked_lines(picked, label_width(region), *label_font())):
                col.label(text=line, icon='INFO' if i == 0 else 'BLANK1')


PICKED_LINES = 8   # lines of the picked pairing's description under the list
# Text width of a label with an icon in a sub-panel at Blender's default sidebar width (229 px,
# UI scale 1), in blf pixels of the 11 pt UI font: under Solve With This Pairing the text
# "#8: handle 1 -> handle" (116 px) was whole and the next word cut (Blender 3.4 window).
LABEL_WIDTH_DEFAULT = 120
SIDEBAR_WIDTH_DEFAULT = 229
# The main panel's icon labels are that much wider (no sub-panel indent): at the default width
# Blender cut "Different topology: source ..." to "Different topology: sourc…" (133 px).
MAIN_PANEL_EXTRA = 10


def picked_description(settings):
    """'#k: <the core's description>' of the pairing picked in the list, '' when none is
    picked. The list's rows show only the number and the energy (the description does not fit
    a row at the default width), and for genus >= 2 most rows read '—': the description tells
    them apart (which handle goes where, 'listed in the short canonical basis', 'the same class
    as candidate 0 up to an isometry', why it was not ranked)."""
    i = int(settings.candidate_index)
    if not 0 <= i < len(settings.candidates):
        return ""
    c = settings.candidates[i]
    text = " ".join(c.description.split())
    return f"#{c.index}: {text}" if text else ""


def label_width(region=None):
    """Text width (blf pixels at UI scale 1) of an icon label in a sub-panel of `region`, the
    sidebar (its default width when unknown)."""
    width = getattr(region, "width", 0) or 0
    if width <= 0:
        return LABEL_WIDTH_DEFAULT
    return max(60, LABEL_WIDTH_DEFAULT + int(width / ui_scale()) - SIDEBAR_WIDTH_DEFAULT)


def ui_scale():
    """The factor of the UI's pixels: the region's pixels include the resolution scale
    (system.ui_scale: 0 in background mode, then the preference's UI scale)."""
    prefs = bpy.context.preferences
    return getattr(prefs.system, "ui_scale", 0.0) or prefs.view.ui_scale or 1.0


def label_font():
    """(points, UI scale) the labels' text is drawn at: the UI style's label points (11 by
    default; 'widget_label', or 'widget' where a version has no label style) and ui_scale()."""
    style = bpy.context.preferences.ui_styles[0]
    font = getattr(style, "widget_label", None) or getattr(style, "widget", None)
    return float(getattr(font, "points", 11) or 11), float(ui_scale())


def text_width(text, points=11, scale=1.0):
    """Width of `text` in the UI's label font of `points` drawn at UI scale `scale` (the size
    in pixels, hinted), in pixels at UI scale 1."""
    import blf
    size = points * scale
    try:
        blf.size(0, size)
    except TypeError:          # Blender 3.x also takes a dpi
        blf.size(0, size, 72)
    return blf.dimensions(0, text)[0] / scale


@functools.lru_cache(maxsize=32)
def picked_lines(text, width=LABEL_WIDTH_DEFAULT, points=11, scale=1.0):
    """`text` wrapped into lines of at most `width` pixels (at UI scale 1) in the label font
    of `points` at UI scale `scale` (label_font()); a word wider than a line is cut; at most
    PICKED_LINES lines, the last one ending in '…' when the rest is left out. A tuple, cached
    on all four: the panel draws on every redraw (each mouse move over it), and the wrap
    measures each word's width with blf several times; they change only when another row is
    picked, the sidebar is resized, or the font size or UI scale is changed."""
    def fits(t):
        return text_width(t, points, scale) <= width
    lines, cur = [], ""
    for w in text.split():
        cand = (cur + " " + w) if cur else w
        if cur and not fits(cand):
            lines.append(cur)
            cur = w
        else:
            cur = cand
        while not fits(cur) and len(cur) > 1:   # one word too wide for a line
            k = len(cur)
            while k > 1 and not fits(cur[:k]):
                k -= 1
            lines.append(cur[:k])
            cur = cur[k:]
    if cur:
        lines.append(cur)
    if len(lines) > PICKED_LINES:
        lines = lines[:PICKED_LINES]
        last = lines[-1]
        while last and not fits(last + "…"):
            last = last[:-1]
        lines[-1] = last.rstrip() + "…"
    return tuple(lines)


class SURFMAP_PT_outputs(_SubPanel, bpy.types.Panel):
    bl_idname = "SURFMAP_PT_outputs"
    bl_label = "Outputs"

    def draw(self, context):
        draw_outputs(self.layout, context.scene.surfmap, context)


def draw_outputs(layout, settings, context):
    col = layout.column(align=True)
    row = col.row(align=True)
    row.prop(settings, "write_uvs", toggle=True)
    row.prop(settings, "write_morph", toggle=True)
    row.prop(settings, "write_distortion", toggle=True)
    row = col.row(align=True)
    row.prop(settings, "write_uvs_before", toggle=True)
    row.prop(settings, "write_refined", toggle=True)
    sub = layout.column()
    sub.use_property_split = True
    sub.use_property_decorate = False
    sub.prop(settings, "morph_space")
    layout.label(text="Show on both objects:")
    grid = layout.grid_flow(row_major=True, columns=2, even_columns=True, align=True)
    for name, text in ((map_job.DILATATION_COLOURS, "Stretch D'"),
                       (map_job.CONFORMAL_COLOURS, "Area"),
                       (map_job.CURVATURE_COLOURS, "Curvature")):
        op = grid.operator("surfmap.show_output", text=text, icon='COLOR',
                           depress=settings.shown == name)
        op.what, op.attribute = 'COLOURS', name
    grid.operator("surfmap.show_output", text="Texture", icon='TEXTURE',
                  depress=settings.shown == 'TEXTURE').what = 'TEXTURE'
    grid.operator("surfmap.show_output", text="Morph", icon='SHAPEKEY_DATA',
                  depress=settings.shown == 'MORPH').what = 'MORPH'
    grid.operator("surfmap.show_output", text="Back", icon='LOOP_BACK').what = 'BACK'
    legend = settings.legends.get(settings.shown) if settings.shown else None
    if legend is not None:
        box = layout.box()
        box.label(text=legend.title, icon='COLOR')
        row = box.row(align=True)
        row.prop(legend, "lo", text="Low")
        row.prop(legend, "hi", text="High")
        row = box.row(align=True)
        row.prop(settings, "colour_percentile")
        row.operator("surfmap.colours_from_data", text="", icon='FILE_REFRESH')
    if settings.shown == 'MORPH':
        from .ops_view import morph_keys, pair_objects
        obs = pair_objects(context)
        if len(obs) == 2:
            box = layout.box()
            for ob, key in zip(obs, morph_keys(*obs)):
                if key is not None:
                    box.prop(key, "value", text=ob.name, slider=True)
    col = layout.column(align=True)
    col.label(text="Again from the stored map:")
    row = col.row(align=True)
    row.operator("surfmap.transfer_uvs", text="UVs")
    row.operator("surfmap.create_morph", text="Morph")
    row.operator("surfmap.paint_distortion", text="Colours")
    row = col.row(align=True)
    # (half a default-width sidebar holds about 9 characters beside an icon)
    row.operator("surfmap.bake_textures", text="Bake", icon='TEXTURE')
    row.operator("surfmap.cut_along_seams", text="Cut Seams", icon='UV')
    col.operator("surfmap.verify_map", text="Verify", icon='CHECKMARK')
    batch_operators.draw_rows(layout)   # many objects: map onto selected, compare selected


class SURFMAP_PT_result(_SubPanel, bpy.types.Panel):
    bl_idname = "SURFMAP_PT_result"
    bl_label = "Result"

    @classmethod
    def poll(cls, context):
        s = context.scene.surfmap
        return not computing() and bool(s.map_status or len(s.summary_rows))

    def draw(self, context):
        draw_result(self.layout, context.scene.surfmap)


def result_lines(rows):
    """The Result panel's lines from the run's (label, value) rows (ops_map.summary_rows):
    "Time" with the stage split ('  solve', ... as one wrapped text) right under "Energy",
    "Mean D'" and "Max D'" on one line, the other rows as they are. After a run the panel
    sits under Outputs at the sidebar's bottom edge: the fewer lines, the more of it shows."""
    rows = [(name, value) for name, value in rows]
    d = dict(rows)
    max_d = d.get("Max D'")
    stages = [f"{name.strip()} {value.replace(' s', '')}" for name, value in rows
              if name.startswith("  ") and value != "0.0 s"]   # (under 0.05 s: left out)
    timing = []
    if "Time" in d:
        timing.append(("Time", d["Time"]))
        if stages:
            timing += [("", line) for line in _wrap_items(stages[:-1] + [stages[-1] + " s"],
                                                         WRAP)]
    out = []
    for name, value in rows:
        if name.startswith("  ") or name == "Time" or (name == "Max D'" and "Mean D'" in d):
            continue
        if name == "Mean D'" and max_d is not None:
            name, value = "D' mean/max", f"{value} / {max_d}"
        out.append((name, value))
        if name == "Energy":
            out += timing
            timing = []
    return out + timing


def _wrap_items(items, width):
    """items joined by ', ' into lines of at most `width` characters, an item never split
    across lines (the stage split wrapped by words left its unit 's' alone on a line)."""
    lines, cur = [], ""
    for item in items:
        if cur and len(cur) + len(", ") + len(item) > width - 1:   # (room for the comma)
            lines.append(cur + ",")
            cur = item
        else:
            cur = f"{cur}, {item}" if cur else item
    return lines + ([cur] if cur else [])


def draw_result(layout, settings):
    col = layout.column(align=True)
    for name, value in result_lines((r.name, r.value) for r in settings.summary_rows):
        if not name:
            col.label(text=value)
            continue
        split = col.split(factor=0.45, align=True)
        split.label(text=name)
        split.label(text=value)
    if settings.map_status and not len(settings.summary_rows):
        _lines(col, settings.map_status, 8)
    if settings.landmark_status:
        _lines(layout.column(align=True), settings.landmark_status, 4, icon='PINNED')


classes = (SURFMAP_UL_candidates, SURFMAP_PT_main, SURFMAP_PT_loops, SURFMAP_PT_map,
           SURFMAP_PT_outputs, SURFMAP_PT_result)

register, unregister = bpy.utils.register_classes_factory(classes)
