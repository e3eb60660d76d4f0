"""The colour legend drawn in the 3D views (bpy, gpu, blf; no bgl, so it loads on Blender 3.4
and 4.x): when the view shows a colour output (surfmap.show_output), a colour bar with its
numbers and title in the lower left corner; when the scene has cut-loop curves, the names
a1, b1, ... in their colours."""
import blf
import bpy
import gpu
from gpu_extras.batch import batch_for_shader

from . import colours

_handle = None
BAR_W, BAR_H, PAD = 180, 12, 14


def _shader(name):
    """Built-in shaders lost their 2D_/3D_ prefixes in Blender 3.4+ (4.0 removed the old)."""
    for n in (name, "2D_" + name):
        try:
            return gpu.shader.from_builtin(n)
        except (ValueError, TypeError):
            continue
    return None


def _rects(x, y, w, h, rgb_left, rgb_right):
    """Two triangles of a horizontal rectangle shaded from one colour to the other."""
    pos = [(x, y), (x + w, y), (x + w, y + h), (x, y), (x + w, y + h), (x, y + h)]
    cl = tuple(rgb_left) + (1.0,)
    cr = tuple(rgb_right) + (1.0,)
    return pos, [cl, cr, cr, cl, cr, cl]


def bar_geometry(scale, x, y, w, h):
    """Vertex positions and colours (display sRGB) of a colour bar for a scale's stops."""
    stops = colours.STOPS[scale]
    k = len(stops) - 1
    pos, col = [], []
    for i in range(k):
        p, c = _rects(x + w * i / k, y, w / k, h, stops[i], stops[i + 1])
        pos += p
        col += c
    return pos, col


def legend_lines(settings):
    """What the legend shows: None, or (title, scale, tick labels) of the shown colours."""
    item = settings.legends.get(settings.shown) if settings.shown else None
    if item is None:
        return None
    _, _, labels = colours.legend_stops(item.scale, item.lo, item.hi, ticks=3)
    return item.title, item.scale, labels


def loop_names(scene):
    """(name, linear rgba) of the cut-loop curves in the scene, a1, b1, a2, ... once each."""
    from .blender_io import OWNER_KEY
    from .cut_loops import pair_colour
    names = sorted({ob.name.rsplit(" ", 1)[-1] for ob in scene.objects if ob.get(OWNER_KEY)},
                   key=lambda n: (int(n[1:]) if n[1:].isdigit() else 0, n[0]))
    out = []
    for n in names:
        if len(n) >= 2 and n[0] in "ab" and n[1:].isdigit():
            k = (int(n[1:]) - 1) * 2 + (0 if n[0] == "a" else 1)
            out.append((n, pair_colour(k)))
    return out


def _text(x, y, text, size=12, rgba=(1, 1, 1, 1)):
    blf.position(0, x, y, 0)
    try:
        blf.size(0, size)
    except TypeError:          # Blender 3.x also takes a dpi
        blf.size(0, size, 72)
    blf.color(0, *rgba)
    blf.draw(0, text)


def draw():
    context = bpy.context
    scene = context.scene
    settings = getattr(scene, "surfmap", None)
    if settings is None:
        return
    shader = _shader("SMOOTH_COLOR")
    flat = _shader("UNIFORM_COLOR")
    x, y = PAD, PAD + 20
    got = legend_lines(settings)
    if got is not None and shader is not None:
        title, scale, labels = got
        pos, col = bar_geometry(scale, x, y + 16, BAR_W, BAR_H)
        gpu.state.blend_set('ALPHA')
        batch_for_shader(shader, 'TRIS', {"pos": pos, "color": col}).draw(shader)
        for i, lab in enumerate(labels):
            w, _ = blf.dimensions(0, lab)
            lx = x + BAR_W * i / (len(labels) - 1) - w * i / (len(labels) - 1)
            _text(lx, y, lab)
        _text(x, y + 16 + BAR_H + 6, title, 13)
        if scale == "SEQUENTIAL" and flat is not None:
            bx = x + BAR_W + 10
            flat.bind()
            flat.uniform_float("color", colours.INVALID + (1.0,))
            batch_for_shader(flat, 'TRIS', {"pos": _rects(bx, y + 16, BAR_H, BAR_H, (0, 0, 0),
                                                          (0, 0, 0))[0]}).draw(flat)
            _text(bx + BAR_H + 4, y + 16, "flipped")
        gpu.state.blend_set('NONE')
        y += 16 + BAR_H + 30
    names = loop_names(scene)
    if names and flat is not None:
        cx = x
        for n, rgba in names:
            srgb = [c * 12.92 if c <= 0.0031308 else 1.055 * c ** (1 / 2.4) - 0.055
                    for c in rgba[:3]]
            flat.bind()
            flat.uniform_float("color", tuple(srgb) + (1.0,))
            batch_for_shader(flat, 'TRIS', {"pos": _rects(cx, y, 10, 10, (0, 0, 0),
                                                          (0, 0, 0))[0]}).draw(flat)
            _text(cx + 13, y, n)
            cx += 13 + blf.dimensions(0, n)[0] + 10
        _text(x, y + 16, "Cut loops", 13)


def register():
    global _handle
    if _handle is None and not bpy.app.background:
        _handle = bpy.types.SpaceView3D.draw_handler_add(draw, (), 'WINDOW', 'POST_PIXEL')


def unregister():
    global _handle
    if _handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_handle, 'WINDOW')
        _handle = None


