"""Scene settings (one PropertyGroup: scene.surfmap) and the add-on preferences."""
import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty,
                       FloatVectorProperty, IntProperty, PointerProperty, StringProperty)

from . import native


class SURFMAP_PG_candidate(bpy.types.PropertyGroup):
    """One handle correspondence (homotopy class) of the last run, with its energy."""
    index: IntProperty(name="Index")
    description: StringProperty(name="Description")
    energy: FloatProperty(name="Energy")
    solved: BoolProperty(name="Solved", default=True,
                         description="False when the core could not solve this class (no energy)")
    landmark_energy: FloatProperty(
        name="Energy With Landmarks", default=float("nan"),
        description="With landmarks: the class's energy with them held as the map holds them "
                    "(the ranking's key; inf where they cannot be held bijectively, nan when "
                    "not computed: its lower bound could not beat the best)")


class SURFMAP_PG_settings(bpy.types.PropertyGroup):
    source_base_vertex: IntProperty(
        name="Source Base Vertex", default=-1, min=-1,
        description="Vertex where the source's loops meet (-1: chosen automatically)")
    target_base_vertex: IntProperty(
        name="Target Base Vertex", default=-1, min=-1,
        description="Vertex where the target's (active object's) loops meet "
                    "(-1: chosen automatically)")
    loop_bevel: FloatProperty(
        name="Loop Bevel", default=0.005, min=0.0, soft_max=0.05, precision=4,
        description="Thickness of the loop curves, as a fraction of the object's size "
                    "(bounding-box diagonal)")
    mark_seams: BoolProperty(
        name="Mark Seams", default=True,
        description="Mark the mesh edges along the loops as UV seams (the cut graph: "
                    "unwrapping then gives one island)")
    status: StringProperty(
        name="Status", default="",
        description="Result of the last run")
    # --- the map
    homotopy: IntProperty(
        name="Handle Correspondence", default=-1, min=-1,
        description="Homotopy class of the map: index into the candidates listed after a run "
                    "(-1: the one of lowest energy)")
    candidates: CollectionProperty(type=SURFMAP_PG_candidate)
    chosen_candidate: IntProperty(name="Chosen Candidate", default=-1)
    landmark_mode: EnumProperty(
        name="Landmarks", default='NONE',
        items=(('NONE', "None", "No landmarks"),
               ('GROUPS', "Vertex Groups", "Pairs of vertex groups of the same name starting "
                "with 'lm_' on both objects (e.g. lm_nose): each group's vertex of largest "
                "weight is held on the other's"),
               ('SELECTED', "Selected Vertices", "The vertices selected on each object, in "
                "selection order, paired one to one")))
    method: EnumProperty(
        name="Method", default='NEWTON',
        items=(('NEWTON', "Newton", "Newton's method on the harmonic energy (fast)"),
               ('RELAXATION', "Relaxation", "The paper's per-vertex heat-diffusion relaxation "
                "(slow; for comparison)")))
    tolerance: FloatProperty(
        name="Tolerance", default=0.0, min=0.0, precision=10, step=0.0001,
        description="Convergence tolerance of the solve (0: the core's default)")
    source_weights: EnumProperty(
        name="Source Weights", default='AUTO',
        items=(('AUTO', "Automatic", "Cotangent weights of the source's intrinsic Delaunay "
                "triangulation; solved again with positive weights on the source's own edges "
                "when the images of its faces fold (slivers, caps)"),
               ('INTRINSIC', "Intrinsic Delaunay", "Intrinsic Delaunay cotangent weights only "
                "(a fold of the source's own faces is then an error)"),
               ('OWN', "Own Edges", "Positive weights on the source's own edges (embeds its "
                "faces; more distortion where both work)")))
    write_uvs: BoolProperty(name="UVs", default=True,
                            description="Transfer every UV map of the source onto the target")
    write_uvs_before: BoolProperty(
        name="Before UVs", default=False,
        description="Also transfer the UVs through the initial map (before the optimisation), "
                    "as UV maps 'surfmap before <name>' on the target, for comparison "
                    "(genus >= 1)")
    write_morph: BoolProperty(name="Morph", default=True,
                              description="Shape keys morphing each object into the other")
    write_distortion: BoolProperty(
        name="Distortion", default=True,
        description="Colour attributes of the dilatation, conformal factor and mean-curvature "
                    "difference on the source")
    write_refined: BoolProperty(
        name="Refined Morph", default=False,
        description="Also a new object: the source refined where its image is long or bends "
                    "(paper §VII-E), with a shape key onto the target that follows its detail")
    morph_space: EnumProperty(
        name="Morph Space", default='IN_PLACE',
        items=(('IN_PLACE', "In Place", "Each object takes the other's shape (with its "
                "rotation and scale) around its own origin"),
               ('WORLD', "Onto Other", "Each object moves onto the other where it stands")))
    dilatation_range: FloatVectorProperty(
        name="D' Colour Range", size=2, default=(1.0, 2.0),
        description="Dilatation values at the two ends of the last distortion colour scale")
    map_status: StringProperty(name="Map Status", default="",
                               description="Result of the last Compute Map")
    landmark_status: StringProperty(
        name="Landmark Status", default="",
        description="How the last Compute Map held its landmarks: plain pins, the barrier "
                    "continuation (and its steps) or carried neighbourhoods; empty without")


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


classes = (SURFMAP_PG_candidate, SURFMAP_PG_settings, SURFMAP_AP_preferences)


def register():
    for c in classes:
        bpy.utils.register_class(c)
    bpy.types.Scene.surfmap = PointerProperty(type=SURFMAP_PG_settings)


def unregister():
    del bpy.types.Scene.surfmap
    for c in reversed(classes):
        bpy.utils.unregister_class(c)
