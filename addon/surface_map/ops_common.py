"""What every Surface Map operator shares (bpy): the native module, the Object Mode check and
the source/target pick from the selection."""
import bpy  # noqa: F401

from . import native
from .properties import extra_module_dirs
from .side import ObjectProblem


def surfmap_module(context):
    return native.load(extra_dirs=extra_module_dirs(context))


class errors_reported:
    """`with errors_reported(operator, sm) as r:` around a step that reads the scene and calls
    the core: an ObjectProblem (its message) or a surfmap error (`sm.Error`, "surfmap: ...")
    raised inside goes to operator.report as an ERROR and sets r.failed; other exceptions
    pass."""

    def __init__(self, operator, sm=None):
        self.operator, self.sm, self.failed = operator, sm, False

    def __enter__(self):
        return self

    def __exit__(self, kind, error, traceback):
        if kind is None:
            return False
        if issubclass(kind, ObjectProblem):
            message = str(error)
        elif self.sm is not None and issubclass(kind, self.sm.Error):
            message = f"surfmap: {error}"
        else:
            return False
        self.operator.report({'ERROR'}, message)
        self.failed = True
        return True


def native_and_object_mode(cls, context):
    """The poll precondition every Surface Map operator shares: the native module is there
    and Blender is in Object Mode (otherwise the reason goes to poll_message_set)."""
    if surfmap_module(context) is None:
        cls.poll_message_set("The surfmap native module is missing (see the Surface Map panel)")
        return False
    return object_mode(cls, context)


def object_mode(cls, context):
    """The poll precondition of the operators that work from the stored map alone (no native
    call): Blender is in Object Mode (otherwise the reason goes to poll_message_set)."""
    if context.mode != 'OBJECT':
        cls.poll_message_set("Switch to Object Mode")
        return False
    return True


def pick_objects(context):
    """(source, target) following Blender's selected-to-active habit: the active object is the
    target, the other selected mesh the source (None with a single mesh). Raises
    ObjectProblem with a message when the selection does not fit."""
    selected = list(context.selected_objects)
    active = context.active_object
    if active is not None and active.select_get() and active not in selected:
        selected.append(active)
    others = [o for o in selected if o.type != 'MESH']
    if others:
        o = others[0]
        raise ObjectProblem(f"'{o.name}' is a {o.type.lower()}, not a mesh: "
                            f"select one or two mesh objects")
    if not selected:
        raise ObjectProblem("no mesh selected: select one or two mesh objects")
    if len(selected) > 2:
        raise ObjectProblem(f"{len(selected)} objects selected: select one mesh, or two "
                            f"(the active one is the target, the other the source)")
    if len(selected) == 1:
        return None, selected[0]
    if active not in selected:
        raise ObjectProblem("two meshes selected but neither is active: the active object "
                            "is the target (click it last)")
    source = selected[0] if selected[1] == active else selected[1]
    return source, active
