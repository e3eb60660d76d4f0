"""Scene settings (one PropertyGroup: scene.surfmap) and the add-on preferences."""
import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty,
                       FloatVectorProperty, IntProperty, PointerProperty, StringProperty)

from . import native


def _recolour(self, context):
    from . import ops_view
    ops_view.recolour(context)


def _percentile_changed(self, context):
    from . import ops_view
    ops_view.recolour(context, from_percentile=True)


def _active_job():
    from . import map_job
    return map_job.ACTIVE.get("job")


def _progress_get(self):
    job = _active_job()
    return 100.0 * job.fraction if job is not None else 0.0


def _stage_get(self):
    job = _active_job()
    return job.stage_text(short=True) if job is not None else ""


def _run_get(self):
    job = _active_job()
    return job.run_text() if job is not None else ""


def _tolerance_text_get(self):
    t = self.tolerance
    return "default" if t <= 0 else f"{t:.1e}"


def _tolerance_text_set(self, text):
    text = text.strip().lower()
    if text in ("", "0", "default", "auto"):
        self.tolerance = 0.0
        return
    try:
        value = float(text)
    except ValueError:
        return  # not a number: keep the value (the field shows it again)
    if value >= 0:
        self.tolerance = value


def _homotopy_auto_get(self):
    return self.homotopy < 0


def _homotopy_auto_set(self, value):
    if value:
        self.homotopy = -1
    elif self.homotopy < 0:
        self.homotopy = max(self.chosen_candidate, 0)


def _boundary_pairing_update(self, context):
    # Typing loops means giving them; clearing the text goes back to automatic.
    self.boundary_pairing_auto = not self.boundary_pairing.strip()


class SURFMAP_PG_candidate(bpy.types.PropertyGroup):
    """One way of pairing the handles of the source with those of the target (a homotopy class
    of maps), with its energy."""
    index: IntProperty(name="Index")
    description: StringProperty(name="Description")
    energy: FloatProperty(name="Energy", description="Energy of the map with this pairing "
                          "(the solved energy, or the estimate when only estimated)")
    solved: BoolProperty(name="Solved", default=True,
                         description="The map with this pairing was solved (else estimated)")
    estimated: BoolProperty(name="Estimated", default=False,
                            description="The energy is an estimate (a quick solve on a "
                            "coarser copy); it was not solved in full")
    words: StringProperty(
        name="Words", default="",
        description="Genus 2 and up: the pairing as words (JSON), by which the next run is asked "
                    "for it (its number in this list may name another pairing there)")
    landmark_energy: FloatProperty(
        name="Energy With Landmarks", default=float("nan"),
        description="With landmarks: the energy with them held (the ranking's key; inf where "
                    "they cannot be held without folding, nan when not computed)")


class SURFMAP_PG_row(bpy.types.PropertyGroup):
    """One row of the run summary: name is the label."""
    value: StringProperty(name="Value")


class SURFMAP_PG_legend(bpy.types.PropertyGroup):
    """The colour scale of one colour output (name: its colour attribute)."""
    title: StringProperty(name="Title")
    scale: StringProperty(name="Scale", default="SEQUENTIAL")
    lo: FloatProperty(name="Low", precision=3, update=_recolour,
                      description="Value at the low end of the colours")
    hi: FloatProperty(name="High", precision=3, update=_recolour,
                      description="Value at the high end of the colours")


class SURFMAP_PG_settings(bpy.types.PropertyGroup):
    source_base_vertex: IntProperty(
        name="Source Base", default=-1, min=-1,
        description="Vertex of the source where its loops meet (-1: picked automatically)")
    target_base_vertex: IntProperty(
        name="Target Base", default=-1, min=-1,
        description="Vertex of the target (the active object) where its loops meet "
                    "(-1: picked automatically)")
    loop_bevel: FloatProperty(
        name="Thickness", default=0.005, min=0.0, soft_max=0.05, precision=4,
        description="Thickness of the loop curves, as a fraction of the object's size")
    mark_seams: BoolProperty(
        name="Mark Seams", default=True,
        description="Mark the mesh edges along the loops as UV seams (Unwrap then gives one "
                    "island)")
    status: StringProperty(name="Status", default="", description="Result of the last run")
    # --- the map
    homotopy: IntProperty(
        name="Pairing", default=-1, min=-1,
        description="Which handle of the source goes to which handle of the target: a number "
                    "from the list shown after a run (-1: the pairing with the lowest energy)")
    # The panel shows Auto (a check box) rather than the -1 above: ticked, the pairing of lowest
    # energy; unticked, the number beside it (the chosen one of the last run to start with).
    homotopy_auto: BoolProperty(
        name="Auto", get=_homotopy_auto_get, set=_homotopy_auto_set,
        description="Pair the handles automatically: the pairing with the lowest energy (untick "
                    "to give a number from the list shown after a run)")
    candidates: CollectionProperty(type=SURFMAP_PG_candidate)
    candidate_index: IntProperty(name="Picked Pairing", default=-1,
                                 description="The pairing picked in the list")
    chosen_candidate: IntProperty(name="Chosen Pairing", default=-1)
    landmark_mode: EnumProperty(
        name="Landmarks", default='NONE',
        items=(('NONE', "None", "No landmarks"),
               ('GROUPS', "Vertex Groups", "Pairs of vertex groups of the same name starting "
                "with 'lm_' on both objects (e.g. lm_nose): each group's vertex of largest "
                "weight is held on the other's"),
               ('SELECTED', "Selected Vertices", "The vertices selected on each object, in "
                "selection order, paired one to one")),
        description="Points of the source held on chosen points of the target")
    method: EnumProperty(
        name="Solver", default='NEWTON',
        items=(('NEWTON', "Newton", "Newton's method (fast)"),
               ('RELAXATION', "Relaxation", "The paper's per-vertex relaxation (slow; for "
                "comparison)")),
        description="How the smoothest map is found")
    tolerance: FloatProperty(
        name="Tolerance", default=0.0, min=0.0, precision=10, step=0.0001,
        description="When the solve stops: its relative gradient tolerance (0: the default)")
    tolerance_text: StringProperty(
        name="Tolerance", get=_tolerance_text_get, set=_tolerance_text_set,
        description="When the solve stops: its relative gradient tolerance, e.g. 1e-10 "
                    "('default': the solver's own)")
    source_weights: EnumProperty(
        name="Weights", default='AUTO',
        items=(('AUTO', "Automatic", "Intrinsic weights; the source's own edges where the "
                "map would fold its faces (slivers, caps)"),
               ('INTRINSIC', "Intrinsic", "Intrinsic Delaunay weights only (a fold of the "
                "source's faces is then an error)"),
               ('OWN', "Own Edges", "The source's own edges (never folds; a little more "
                "stretch)")),
        description="How the source's edges are weighted in the energy")
    boundary_pairing: StringProperty(
        name="Boundary Loops", default="", update=_boundary_pairing_update,
        description="Open meshes: the target boundary loop of each source boundary loop, loops "
                    "numbered longest first (e.g. '1 0' maps an annulus's loops crosswise)")
    boundary_pairing_auto: BoolProperty(
        name="Auto", default=True,
        description="Open meshes: pair the boundary loops automatically (disks and annuli: loop "
                    "i onto loop i, longest first; otherwise the pairing of lowest energy). "
                    "Untick to give the target loop of each source loop")
    write_uvs: BoolProperty(name="UVs", default=True,
                            description="Copy every UV map of the source onto the target")
    write_uvs_before: BoolProperty(
        name="UVs Before", default=False,
        description="Also copy the UVs through the starting map (before the optimisation), "
                    "as 'surfmap before <name>' on the target, for comparison")
    write_morph: BoolProperty(name="Morph", default=True,
                              description="Shape keys morphing each object into the other")
    write_distortion: BoolProperty(
        name="Colours", default=True,
        description="Colour both objects by how much the map stretches (D'), grows or "
                    "shrinks area, and changes curvature")
    write_refined: BoolProperty(
        name="Refined Morph", default=False,
        description="Also a new object: the source with more detail where its image is long "
                    "or bends, morphing onto the target")
    morph_space: EnumProperty(
        name="Morph", default='IN_PLACE',
        items=(('IN_PLACE', "In Place", "Each object takes the other's shape around its own "
                "origin"),
               ('WORLD', "Onto Other", "Each object moves onto the other where it stands")),
        description="Where the morphed shape goes")
    dilatation_range: FloatVectorProperty(
        name="D' Colour Range", size=2, default=(1.0, 2.0),
        description="Dilatation values at the two ends of the last distortion colour scale")
    map_status: StringProperty(name="Map Status", default="",
                               description="Result of the last Compute Map")
    landmark_status: StringProperty(
        name="Landmark Status", default="",
        description="How the last Compute Map held its landmarks; empty without")
    # --- the last run and its outputs
    summary_rows: CollectionProperty(type=SURFMAP_PG_row)
    legends: CollectionProperty(type=SURFMAP_PG_legend)
    legend_pair: StringProperty(name="Coloured Objects", default="",
                                description="Source and target of the colours (tab-separated)")
    colour_percentile: FloatProperty(
        name="Percentile", default=99.0, min=50.0, max=100.0, precision=1,
        update=_percentile_changed,
        description="The colours' high end is this percentile of the values (the highest "
                    "values beyond it share the end colour)")
    shown: StringProperty(name="Shown", default="",
                          description="What the viewport shows: '', a colour attribute, "
                          "'TEXTURE' or 'MORPH'")
    shown_saved: StringProperty(name="Saved View", default="",
                                description="The viewport shading before Show (restored by Back)")
    max_tick_gap: FloatProperty(name="Longest UI Pause", default=0.0, unit='TIME_ABSOLUTE',
                                description="Longest gap between the UI timer's ticks during "
                                            "the last run (s)")
    progress: FloatProperty(name="Progress", subtype='PERCENTAGE', min=0.0, max=100.0,
                            precision=0, get=_progress_get,
                            description="How far the running computation is")
    progress_stage: StringProperty(name="Stage", get=_stage_get,
                                   description="What the running computation is doing")
    progress_run: StringProperty(name="Run", get=_run_get,
                                 description="The run after the main one, or the retry, that "
                                             "the stage belongs to (empty in the main run)")


class SURFMAP_AP_preferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    module_path: StringProperty(
        name="Module Folder", subtype='DIR_PATH', default="",
        description="Folder that contains the surfmap package (e.g. <repo>/build/python); "
                    "only needed when the add-on does not ship it")

    def draw(self, context):
        layout = self.layout
        layout.prop(self, "module_path")
        mod = native.load(extra_dirs=(bpy.path.abspath(self.module_path),) if self.module_path else ())
        if mod is not None:
            layout.label(text=f"surfmap loaded from {native.origin()}", icon='CHECKMARK')
        else:
            layout.label(text="surfmap native module missing", icon='ERROR')
            for line in _wrap(native.error(), 90):
                layout.label(text=line)


def _wrap(text, width):
    words, lines, cur = text.split(), [], ""
    for w in words:
        if cur and len(cur) + 1 + len(w) > width:
            lines.append(cur)
            cur = w
        else:
            cur = (cur + " " + w).strip()
    if cur:
        lines.append(cur)
    return lines


def extra_module_dirs(context):
    """The folder from the add-on preferences, if any."""
    addon = context.preferences.addons.get(__package__) if context else None
    if addon is not None and addon.preferences is not None and addon.preferences.module_path:
        return (bpy.path.abspath(addon.preferences.module_path),)
    return ()


classes = (SURFMAP_PG_candidate, SURFMAP_PG_row, SURFMAP_PG_legend, SURFMAP_PG_settings,
           SURFMAP_AP_preferences)


def register():
    for c in classes:
        bpy.utils.register_class(c)
    bpy.types.Scene.surfmap = PointerProperty(type=SURFMAP_PG_settings)


def unregister():
    del bpy.types.Scene.surfmap
    for c in reversed(classes):
        bpy.utils.unregister_class(c)
