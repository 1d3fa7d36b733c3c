"""springbake's bridge to usd-core (the `pxr` package), embedded in Rust with pyo3.

The Rust side (`springbake-usd`) calls exactly three functions here:

* `read_stage(path, root)` -> dict: refuses a stage with a layer outside the folder `root`;
  the layers it names that usd-core cannot read (MaterialX) and its composition errors;
  stage metadata and, per UsdGeomMesh, its raw arrays as little-endian byte strings
  (points, faceVertexCounts/Indices, normals, st, world matrix).
  Triangulation, primvar expansion and vertex splitting happen in Rust.
* `write_source_stage(source_path, out_path, spec)`: flatten the source stage, author the baked
  `points` (and `normals`, `extent`) time samples on the named mesh prims, export.
* `write_new_stage(out_path, spec)`: build a new stage (Xform + Mesh per baked mesh).

Every failure is raised as `BridgeError(message, location)`, `location` being a prim or
attribute path when one applies. Bulk data crosses the boundary as bytes (buffer protocol on
both sides), never one Python call per vertex.
"""

import array
import os
import re
import sys
import tempfile
import threading

from pxr import Ar, Gf, Sdf, Usd, UsdGeom, UsdShade, Vt


class BridgeError(Exception):
    def __init__(self, message, location=None):
        super().__init__(message)
        self.message = message
        self.location = location


_TF_ERROR = re.compile(r"Error in '[^']*' at line \d+ in file [^:]*: '(.*?)'(?:\n|$)", re.S)


def _clean_tf_message(text):
    """usd-core errors embed C++ function names and source lines; keep the messages only."""
    found = [m.strip() for m in _TF_ERROR.findall(str(text))]
    if found:
        return "; ".join(found)
    return str(text).strip()


_TF_WARNING = re.compile(r"^Warning: in \S+ at line \d+ of \S+ -- (.*)$", re.M)

# The process has one stderr: two stages opened at once (bodies imported side by side) would
# swap each other's capture.
_STDERR_CAPTURE = threading.Lock()


def _open(path, warnings=None):
    """Open the stage. Its composition errors (a reference usd-core cannot open) are appended
    to `warnings`, for the importer's notes; usd-core also writes each to the process's stderr,
    C++ locations and all, from whichever thread composed it: those lines are caught there and
    dropped (anything else written meanwhile is passed on)."""
    with _STDERR_CAPTURE, tempfile.TemporaryFile() as captured:
        sys.stderr.flush()
        saved = os.dup(2)
        os.dup2(captured.fileno(), 2)
        try:
            stage = Usd.Stage.Open(path)
        except Exception as e:  # pxr.Tf.ErrorException
            raise BridgeError("usd-core cannot open the stage: " + _clean_tf_message(e))
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            captured.seek(0)
            text = captured.read().decode("utf-8", "replace")
        rest = _TF_WARNING.sub("", text).strip()
        if rest:
            sys.stderr.write(rest + "\n")
    if stage is None:
        raise BridgeError("usd-core cannot open the stage")
    if warnings is not None:
        warnings.extend(str(e).strip() for e in stage.GetCompositionErrors())
    return stage


def _inside(real, root_real):
    return real == root_real or real.startswith(root_real.rstrip(os.sep) + os.sep)


def _outside_error(what, real, root_real):
    return BridgeError(
        "%s resolves to %s, outside the folder %s: springbake reads only files inside it (a "
        "scene file's folder, or a bare mesh's own: to read both, bake a scene file placed in a "
        "folder that holds them)" % (what, real, root_real)
    )


def _readable(path):
    """Whether usd-core has a file format for `path` (usd-core from PyPI has none for MaterialX
    `.mtlx` files, which DCC assets reference for their materials)."""
    extension = os.path.splitext(path)[1].lstrip(".")
    return not extension or Sdf.FileFormat.FindByExtension(extension) is not None


def _check_layer_tree(path, root):
    """Refuse a stage whose layers (subLayers, references, payloads, at any depth) resolve
    outside `root`, symlinks followed, before usd-core opens any of them. A dependency that does
    not exist is left to the stage (usd-core warns and composes without it), and so is one in a
    format usd-core cannot read (the stage composes without it, as Blender's importer does
    without MaterialX): those are returned, for a note."""
    root_real = os.path.realpath(root)
    pending = [path]
    seen = set()
    unread = []
    while pending:
        identifier = pending.pop()
        if identifier in seen:
            continue
        seen.add(identifier)
        try:
            layer = Sdf.Layer.FindOrOpen(identifier)
        except Exception as e:  # pxr.Tf.ErrorException: a parse error, with file and line
            raise BridgeError("usd-core cannot open the stage: " + _clean_tf_message(e))
        if layer is None:
            continue
        for asset in layer.GetCompositionAssetDependencies():
            if not asset:
                continue  # an internal reference (`</Prim>`): this layer itself
            resolved = layer.ComputeAbsolutePath(asset)
            # A file inside a .usdz package is named "package.usdz[inner.usdc]".
            outer = resolved.split("[", 1)[0]
            real = os.path.realpath(outer)
            if not _inside(real, root_real):
                raise _outside_error(
                    "the layer \"%s\" named in %s" % (asset, layer.identifier), real, root_real
                )
            if not _readable(outer):
                if asset not in unread:
                    unread.append(asset)
            elif os.path.isfile(real):
                pending.append(resolved if "[" in resolved else real)
    return unread


def _check_used_layers(stage, root):
    """After opening: every layer the stage actually used (value clips included) is inside."""
    root_real = os.path.realpath(root)
    for layer in stage.GetUsedLayers():
        if layer.anonymous or not layer.realPath:
            continue
        real = os.path.realpath(layer.realPath.split("[", 1)[0])
        if not _inside(real, root_real):
            raise _outside_error("the layer \"%s\"" % layer.identifier, real, root_real)


def _flat(values, kind):
    """A Vt array as (format, bytes). kind 'f' for float vectors/scalars, 'i' for ints."""
    if values is None:
        return None
    view = memoryview(values)
    if kind == "i":
        if view.format in ("i", "l") and view.itemsize == 4:
            return ("i", view.tobytes())
        return ("i", array.array("i", [int(x) for x in values]).tobytes())
    if view.format in ("f", "d"):
        return (view.format, view.tobytes())
    # half precision or anything else: widen element by element (rare).
    out = array.array("d")
    for v in values:
        try:
            out.extend(float(x) for x in v)
        except TypeError:
            out.append(float(v))
    return ("d", out.tobytes())


def _value(attr, time):
    value = attr.Get(time)
    if value is None and attr.HasAuthoredValue():
        value = attr.Get(Usd.TimeCode.EarliestTime())
    return value


def _primvar_data(primvar, time, location):
    try:
        values = primvar.ComputeFlattened(time)
        if values is None:
            values = primvar.ComputeFlattened(Usd.TimeCode.EarliestTime())
    except Exception as e:
        raise BridgeError("cannot resolve primvar: " + _clean_tf_message(e), location)
    if values is None:
        return None
    return {"interpolation": str(primvar.GetInterpolation()), "values": _flat(values, "f")}


_UV_TYPES = ("texCoord2f[]", "texCoord2d[]", "texCoord2h[]")


# Largest texture image read from a USD source.
_MAX_TEXTURE_BYTES = 256 * 1024 * 1024


def _diffuse_texture(shader, root):
    """The image feeding a UsdPreviewSurface's diffuseColor through a UsdUVTexture:
    {"name", "bytes"} (read through usd-core's resolver, so a file inside a .usdz works
    too), or None: not textured, not PNG/JPEG, unreadable, too large, or outside `root`."""
    diffuse = shader.GetInput("diffuseColor")
    source = diffuse.GetConnectedSource() if diffuse else None
    if not source:
        return None
    texture = UsdShade.Shader(source[0].GetPrim())
    if texture.GetIdAttr().Get() != "UsdUVTexture" or not texture.GetInput("file"):
        return None
    asset = texture.GetInput("file").Get()
    resolved = asset.resolvedPath if asset else ""
    if not resolved:
        return None
    outer = os.path.realpath(resolved.split("[", 1)[0])
    if not _inside(outer, os.path.realpath(root)):
        return None
    name = os.path.basename(asset.path)
    if not name.lower().endswith((".png", ".jpg", ".jpeg")):
        return None
    opened = Ar.GetResolver().OpenAsset(Ar.ResolvedPath(resolved))
    if opened is None or opened.GetSize() > _MAX_TEXTURE_BYTES:
        return None
    return {"name": name, "bytes": bytes(opened.GetBuffer())}


def _material_look(material, root="."):
    """A bound material's UsdPreviewSurface values (diffuse colour, opacity, roughness, the
    diffuse texture), or None when its surface is another kind of shader."""
    try:
        shader = material.ComputeSurfaceSource()[0]
        if not shader or shader.GetIdAttr().Get() != "UsdPreviewSurface":
            return None

        def value(name, default):
            source = shader.GetInput(name)
            got = source.Get() if source else None
            return default if got is None else got

        c = value("diffuseColor", Gf.Vec3f(0.18, 0.18, 0.18))
        texture = _diffuse_texture(shader, root)
        if texture is not None:
            c = Gf.Vec3f(1.0, 1.0, 1.0)  # glTF multiplies the image by the factor
        return {
            "name": material.GetPrim().GetName(),
            "base_colour": [float(c[0]), float(c[1]), float(c[2]), float(value("opacity", 1.0))],
            "roughness": float(value("roughness", 0.5)),
            "texture": texture,
        }
    except Exception:
        return None


def _in_point_instancer(prim):
    """Whether an ancestor of `prim` is a UsdGeomPointInstancer (its prototypes are drawn
    only at the instancer's points, not where they sit)."""
    parent = prim.GetParent()
    while parent and not parent.IsPseudoRoot():
        if parent.IsA(UsdGeom.PointInstancer):
            return True
        parent = parent.GetParent()
    return False


# Most instances a PointInstancer may have for springbake to simulate each as a body (a
# scatter of pebbles, not a forest of grass blades); a larger one stays as it is, with a note.
MAX_POINT_INSTANCES = 1000


def _prim_name(text):
    """`text` as a valid prim name."""
    name = re.sub(r"[^A-Za-z0-9_]", "_", text)
    return name if name and not name[0].isdigit() else "_" + name


def _first_sample(*attrs):
    """The earliest time sample of any of `attrs`, or the default time when none has one."""
    times = [t for attr in attrs for t in attr.GetTimeSamples()]
    return Usd.TimeCode(min(times)) if times else Usd.TimeCode.Default()


def _point_instances(stage, time, include_hidden, hidden):
    """The meshes a renderer draws at each PointInstancer's points, realised: one entry per
    (instance, prototype mesh) with the path the baked copy gets (`<instancer>_instances/
    <prototype>_<i>[/<mesh path under the prototype>]`, a sibling of the instancer), the
    prototype mesh prim it copies, and its world matrix (the mesh inside its prototype, the
    prototype root's own transform, the instance's, the instancer's). Masked (invisible)
    instances are left out; an instancer with more than MAX_POINT_INSTANCES instances, or
    inside another one's prototypes, is left as it is and noted in `hidden`. The same stage
    gives the same list, so the import and the export name the copies alike."""
    found = []
    for prim in stage.Traverse(Usd.TraverseInstanceProxies()):
        if not prim.IsA(UsdGeom.PointInstancer):
            continue
        location = str(prim.GetPath())
        if _in_point_instancer(prim):
            hidden.append(location + " (a PointInstancer inside another's prototypes)")
            continue
        imageable = UsdGeom.Imageable(prim)
        if not include_hidden and imageable.ComputeVisibility(time) == UsdGeom.Tokens.invisible:
            hidden.append(location + " (an invisible PointInstancer)")
            continue
        instancer = UsdGeom.PointInstancer(prim)
        prototypes = instancer.GetPrototypesRel().GetForwardedTargets()
        # Where the instances are at the stage's first time sample (or their default).
        at = _first_sample(instancer.GetProtoIndicesAttr(), instancer.GetPositionsAttr())
        indices = instancer.GetProtoIndicesAttr().Get(at) or []
        if len(indices) > MAX_POINT_INSTANCES:
            hidden.append(
                "%s (a PointInstancer of %d instances: more than %d are not simulated)"
                % (location, len(indices), MAX_POINT_INSTANCES)
            )
            continue
        xforms = instancer.ComputeInstanceTransformsAtTime(
            at,
            at,
            UsdGeom.PointInstancer.IncludeProtoXform,
            UsdGeom.PointInstancer.IgnoreMask,
        )
        if xforms is None or len(xforms) != len(indices):
            raise BridgeError(
                "the PointInstancer's positions, orientations or scales do not match its "
                "protoIndices (%d instances)" % len(indices),
                location,
            )
        mask = instancer.ComputeMaskAtTime(at) or []
        instancer_world = imageable.ComputeLocalToWorldTransform(at)
        parent = prim.GetParent()
        group = str(parent.GetPath().AppendChild(_prim_name(prim.GetName() + "_instances")))
        for i, proto_index in enumerate(indices):
            if mask and not mask[i]:
                continue
            if not 0 <= proto_index < len(prototypes):
                raise BridgeError(
                    "protoIndices[%d] is %d, but the PointInstancer has %d prototypes"
                    % (i, proto_index, len(prototypes)),
                    location + ".protoIndices",
                )
            root = stage.GetPrimAtPath(prototypes[proto_index])
            if not root:
                raise BridgeError("the prototype is not on the stage", str(prototypes[proto_index]))
            root_world_inverse = UsdGeom.Imageable(root).ComputeLocalToWorldTransform(time).GetInverse()
            copy = group + "/" + _prim_name("%s_%d" % (root.GetName(), i))
            for mesh in Usd.PrimRange(root, Usd.TraverseInstanceProxies()):
                if not mesh.IsA(UsdGeom.Mesh):
                    continue
                purpose = UsdGeom.Imageable(mesh).ComputePurpose()
                if not include_hidden and purpose in (UsdGeom.Tokens.proxy, UsdGeom.Tokens.guide):
                    continue
                inside = UsdGeom.Imageable(mesh).ComputeLocalToWorldTransform(time) * root_world_inverse
                relative = str(mesh.GetPath().MakeRelativePath(root.GetPath()))
                path = copy if relative == "." else copy + "/" + relative
                found.append(
                    {
                        "path": path,
                        "name": _prim_name("%s_%d" % (mesh.GetName(), i)),
                        "prototype": mesh,
                        "world": inside * xforms[i] * instancer_world,
                        "instancer": location,
                    }
                )
    return found


def _mesh_record(prim, location, name, world, time, root, looks):
    """One mesh's raw arrays, normals, UVs and bound materials for the Rust side."""
    mesh = UsdGeom.Mesh(prim)
    points = _value(mesh.GetPointsAttr(), time)
    counts = _value(mesh.GetFaceVertexCountsAttr(), time)
    indices = _value(mesh.GetFaceVertexIndicesAttr(), time)
    if points is None or counts is None or indices is None:
        raise BridgeError("mesh lacks points, faceVertexCounts or faceVertexIndices", location)
    primvars = UsdGeom.PrimvarsAPI(prim)
    normals = None
    normals_source = None
    pv_normals = primvars.GetPrimvar("normals")
    if pv_normals and pv_normals.HasAuthoredValue():
        normals = _primvar_data(pv_normals, time, location + ".primvars:normals")
        normals_source = "primvars:normals"
    else:
        attr = mesh.GetNormalsAttr()
        if attr.HasAuthoredValue():
            value = _value(attr, time)
            if value is not None:
                normals = {
                    "interpolation": str(mesh.GetNormalsInterpolation()),
                    "values": _flat(value, "f"),
                }
                normals_source = "normals"
    st = None
    for uv_name in ("st", "UVMap", "uv", "st0"):
        pv = primvars.GetPrimvar(uv_name)
        if pv and pv.HasAuthoredValue():
            st = _primvar_data(pv, time, location + ".primvars:" + uv_name)
            break
    if st is None:
        # Any other texture-coordinate primvar (texCoord2f[], e.g. st_faceVarying), the
        # first in name order.
        for pv in sorted(primvars.GetPrimvars(), key=lambda p: p.GetPrimvarName()):
            if str(pv.GetTypeName()) in _UV_TYPES and pv.HasAuthoredValue():
                uv_name = str(pv.GetPrimvarName())
                st = _primvar_data(pv, time, location + ".primvars:" + uv_name)
                break
    material = None
    try:
        bound, _rel = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
        if bound:
            material = bound.GetPrim().GetName()
            looks.setdefault(material, _material_look(bound, root))
    except Exception:
        material = None
    # Materials bound per face through GeomSubsets (family materialBind).
    subsets = []
    try:
        for subset in UsdShade.MaterialBindingAPI(prim).GetMaterialBindSubsets():
            bound, _rel = UsdShade.MaterialBindingAPI(subset.GetPrim()).ComputeBoundMaterial()
            faces = subset.GetIndicesAttr().Get(time)
            if bound and faces is not None:
                subsets.append((bound.GetPrim().GetName(), _flat(faces, "i")))
                looks.setdefault(bound.GetPrim().GetName(), _material_look(bound, root))
    except Exception:
        subsets = []
    return {
        "path": location,
        "name": name,
        "points": _flat(points, "f"),
        "counts": _flat(counts, "i"),
        "indices": _flat(indices, "i"),
        "normals": normals,
        "normals_source": normals_source,
        "st": st,
        "orientation": str(mesh.GetOrientationAttr().Get() or "rightHanded"),
        "material": material,
        "subsets": subsets,
        # Gf matrices are row-major with row vectors (p' = p * M).
        "world": array.array("d", [world[i][j] for i in range(4) for j in range(4)]).tobytes(),
    }


def read_stage(path, root, include_hidden=False):
    """The stage's meshes as a renderer draws them: native instances expanded (each instance
    a mesh of its own, at its instance proxy's path), point instances realised (each a mesh
    of its own, see `_point_instances`; the prototypes are not simulated where they sit),
    invisible and proxy/guide geometry left out unless `include_hidden`. `hidden` lists what
    was left out and why."""
    unread = _check_layer_tree(path, root)
    warnings = []
    stage = _open(path, warnings)
    _check_used_layers(stage, root)
    time = Usd.TimeCode.Default()
    meshes = []
    hidden = []
    looks = {}
    for prim in stage.Traverse(Usd.TraverseInstanceProxies()):
        if not prim.IsA(UsdGeom.Mesh) or _in_point_instancer(prim):
            continue
        location = str(prim.GetPath())
        # What a renderer would not draw is not simulated: invisible prims (their own
        # visibility or an ancestor's) and proxy or guide geometry.
        imageable = UsdGeom.Imageable(prim)
        purpose = imageable.ComputePurpose()
        if not include_hidden and imageable.ComputeVisibility(time) == UsdGeom.Tokens.invisible:
            hidden.append(location + " (invisible)")
            continue
        if not include_hidden and purpose in (UsdGeom.Tokens.proxy, UsdGeom.Tokens.guide):
            hidden.append("%s (purpose %s)" % (location, purpose))
            continue
        world = imageable.ComputeLocalToWorldTransform(time)
        meshes.append(_mesh_record(prim, location, prim.GetName(), world, time, root, looks))
    for instance in _point_instances(stage, time, include_hidden, hidden):
        meshes.append(
            _mesh_record(
                instance["prototype"], instance["path"], instance["name"], instance["world"],
                time, root, looks,
            )
        )
    if not meshes and hidden:
        raise BridgeError(
            "every UsdGeomMesh is invisible, proxy/guide geometry or in a PointInstancer "
            "springbake does not simulate, so there is nothing to simulate: " + ", ".join(hidden[:5])
            + (" …" if len(hidden) > 5 else "")
            + " (set include_hidden = true on the body to simulate invisible and proxy/guide meshes)",
            str(path),
        )
    return {
        "up_axis": str(UsdGeom.GetStageUpAxis(stage)),
        "meters_per_unit": float(UsdGeom.GetStageMetersPerUnit(stage)),
        "meshes": meshes,
        "hidden": hidden,
        "unread": unread,
        "warnings": warnings,
        "materials": [look for look in looks.values() if look is not None],
    }


def _realise_point_instances(stage, baked_paths):
    """Author the realised copies of `_point_instances` that were baked: each a copy of its
    prototype mesh at its own path with its own transform (relative to the instancer's
    parent), and make their instancers invisible (the copies now draw what they drew)."""
    instances = [
        i for i in _point_instances(stage, Usd.TimeCode.Default(), True, [])
        if i["path"] in baked_paths
    ]
    layer = stage.GetRootLayer()
    # Per instancer: its parent's world matrix inverted (the copies sit beside it).
    parent_inverse = {}
    for instance in instances:
        path = Sdf.Path(instance["path"])
        parent_path = path.GetParentPath()
        if instance["instancer"] not in parent_inverse:
            parent = stage.GetPrimAtPath(instance["instancer"]).GetParent()
            world = UsdGeom.Imageable(parent).ComputeLocalToWorldTransform(Usd.TimeCode.Default())
            parent_inverse[instance["instancer"]] = world.GetInverse()
        # Plain transforms between the instancer's parent and the copy.
        Sdf.CreatePrimInLayer(layer, parent_path)
        for ancestor in parent_path.GetPrefixes():
            spec = layer.GetPrimAtPath(ancestor)
            if spec.specifier != Sdf.SpecifierDef:
                spec.specifier = Sdf.SpecifierDef
                spec.typeName = "Xform"
        prototype = instance["prototype"]
        if prototype.IsInstanceProxy() or not layer.GetPrimAtPath(prototype.GetPath()):
            raise BridgeError(
                "this point instance's prototype mesh is inside a native instance; springbake "
                "cannot write it back",
                str(prototype.GetPath()),
            )
        if not Sdf.CopySpec(layer, prototype.GetPath(), layer, path):
            raise BridgeError("usd-core cannot copy the prototype mesh", str(path))
        copy = UsdGeom.Mesh(stage.GetPrimAtPath(path))
        # A material bound on the prototype's root rather than its mesh is bound on the copy.
        bound, _rel = UsdShade.MaterialBindingAPI(prototype).ComputeBoundMaterial()
        if bound:
            UsdShade.MaterialBindingAPI.Apply(copy.GetPrim()).Bind(bound)
        copy.ClearXformOpOrder()
        copy.AddTransformOp().Set(instance["world"] * parent_inverse[instance["instancer"]])
        copy.GetVisibilityAttr().Set(UsdGeom.Tokens.inherited)
    for location in sorted(parent_inverse):
        UsdGeom.Imageable(stage.GetPrimAtPath(location)).MakeInvisible()


def _vec3f_array(data, count):
    view = memoryview(data).cast("B").cast("f", shape=[count, 3])
    return Vt.Vec3fArray.FromBuffer(view)


def _vec2f_array(data, count):
    view = memoryview(data).cast("B").cast("f", shape=[count, 2])
    return Vt.Vec2fArray.FromBuffer(view)


def _int_array(data):
    return Vt.IntArray.FromBuffer(memoryview(data).cast("B").cast("i"))


def _author_frames(mesh, item, frame_count, location):
    """points / normals / extent time samples, frame i at time code i."""
    n = item["point_count"]
    stride = n * 3 * 4
    points = item["points"]
    # Per frame the lowest and highest corner, six f32s (not the raw bytes: slicing those
    # gave Gf.Vec3f byte values, so every sampled extent was garbage and renderers culled).
    extents = memoryview(item["extents"]).cast("B").cast("f")
    if len(extents) != 6 * frame_count:
        raise BridgeError("extent data has the wrong size", location + ".extent")
    normals = item.get("normals")
    normal_count = item.get("normal_count", 0)
    if len(points) != stride * frame_count:
        raise BridgeError("points data has the wrong size", location + ".points")
    points_attr = mesh.CreatePointsAttr()
    extent_attr = mesh.CreateExtentAttr()
    normals_attr = None
    if normals is not None:
        normals_attr = mesh.CreateNormalsAttr()
        mesh.SetNormalsInterpolation(item["normals_interpolation"])
    # A source that was already animated: its old samples would interleave with ours.
    for attr in (points_attr, extent_attr, normals_attr):
        if attr is not None:
            for t in attr.GetTimeSamples():
                attr.ClearAtTime(t)
    nstride = normal_count * 3 * 4
    for f in range(frame_count):
        t = Usd.TimeCode(float(f))
        points_attr.Set(_vec3f_array(points[f * stride:(f + 1) * stride], n), t)
        lo = extents[f * 6:f * 6 + 3].tolist()
        hi = extents[f * 6 + 3:f * 6 + 6].tolist()
        extent_attr.Set(Vt.Vec3fArray([Gf.Vec3f(*lo), Gf.Vec3f(*hi)]), t)
        if normals_attr is not None:
            normals_attr.Set(
                _vec3f_array(normals[f * nstride:(f + 1) * nstride], normal_count), t
            )


def _set_stage_timing(stage, spec):
    fps = float(spec["fps"])
    stage.SetTimeCodesPerSecond(fps)
    stage.SetFramesPerSecond(fps)
    stage.SetStartTimeCode(0.0)
    stage.SetEndTimeCode(float(max(spec["frame_count"] - 1, 0)))


def _export(stage, out_path, texture_files=None):
    """Writes the stage's root layer to `out_path`: .usda, .usdc, or a .usdz package (with
    `texture_files` and what its asset paths name)."""
    if out_path.lower().endswith(".usdz"):
        _export_usdz(stage, out_path, texture_files or [])
        return
    try:
        ok = stage.GetRootLayer().Export(out_path)
    except Exception as e:
        raise BridgeError("usd-core cannot write the layer: " + _clean_tf_message(e))
    if not ok:
        raise BridgeError("usd-core cannot write the layer")


def write_source_stage(source_path, out_path, spec):
    source = _open(source_path)
    try:
        flat_layer = source.Flatten()
    except Exception as e:
        raise BridgeError("usd-core cannot flatten the source stage: " + _clean_tf_message(e))
    folder = spec.get("output_folder")
    if folder and not out_path.lower().endswith(".usdz"):
        # Flattening anchors the source's asset paths (textures) as absolute paths: written
        # relative to the output's folder, the bake and its source's files move together.
        from pxr import UsdUtils

        def relative(asset):
            if os.path.isabs(asset) and "[" not in asset:
                return os.path.relpath(asset, folder)
            return asset

        UsdUtils.ModifyAssetPaths(flat_layer, relative)
    stage = Usd.Stage.Open(flat_layer)
    frame_count = int(spec["frame_count"])
    _realise_point_instances(stage, {item["prim_path"] for item in spec["meshes"]})
    # A baked mesh inside a native instance gets points of its own: its instance stops
    # sharing the prototype (it composes as a plain reference), so it can be authored.
    for item in spec["meshes"]:
        prim = stage.GetPrimAtPath(item["prim_path"])
        while prim and prim.IsInstanceProxy():
            prim = prim.GetParent()
        if prim and prim.IsInstance():
            prim.SetInstanceable(False)
    for item in spec["meshes"]:
        location = item["prim_path"]
        prim = stage.GetPrimAtPath(location)
        if not prim or not prim.IsA(UsdGeom.Mesh):
            raise BridgeError("the source stage has no mesh at this path", location)
        mesh = UsdGeom.Mesh(prim)
        if item.get("drop_primvar_normals"):
            # An indexed or primvar-authored normal set cannot follow the new points; the
            # `normals` attribute written below replaces it.
            prim.RemoveProperty("primvars:normals")
            prim.RemoveProperty("primvars:normals:indices")
        if item.get("normals") is None and item.get("drop_normals"):
            prim.RemoveProperty("normals")
        if not mesh.GetSubdivisionSchemeAttr().HasAuthoredValue():
            # Unauthored means Catmull-Clark: renderers would subdivide the baked cage.
            mesh.CreateSubdivisionSchemeAttr().Set(UsdGeom.Tokens.none)
        _author_frames(mesh, item, frame_count, location)
    # What the import assumed where the source left it unsaid, written down for the next reader.
    if not stage.HasAuthoredMetadata("upAxis"):
        UsdGeom.SetStageUpAxis(
            stage, UsdGeom.Tokens.z if spec["up_axis"] == "Z" else UsdGeom.Tokens.y
        )
    if not stage.HasAuthoredMetadata("metersPerUnit"):
        UsdGeom.SetStageMetersPerUnit(stage, float(spec["meters_per_unit"]))
    default = stage.GetDefaultPrim()
    _author_particles(stage, spec.get("particles"), str(default.GetPath()) if default else "/")
    _set_stage_timing(stage, spec)
    _export(stage, out_path)


def _matrix_from_bytes(data):
    values = array.array("d")
    values.frombytes(data)
    return Gf.Matrix4d(*values)


def _define_materials(stage, materials):
    """UsdPreviewSurface materials under /root/Looks, by material name: diffuse colour,
    opacity, roughness, metallic 0 (what Blender's USD importer turns into a Principled BSDF)."""
    looks = {}
    if not materials:
        return looks
    UsdGeom.Scope.Define(stage, "/root/Looks")
    for m in materials:
        path = "/root/Looks/" + m["prim"]
        material = UsdShade.Material.Define(stage, path)
        shader = UsdShade.Shader.Define(stage, path + "/PreviewSurface")
        shader.CreateIdAttr("UsdPreviewSurface")
        r, g, b, a = (float(c) for c in m["base_colour"])
        diffuse = shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f)
        diffuse.Set(Gf.Vec3f(r, g, b))
        if m.get("texture"):
            # The image through the mesh's `st`, scaled by the colour (white when textured).
            image = _uv_texture(stage, path, "BaseColour", m["texture"], "sRGB")
            image.CreateInput("scale", Sdf.ValueTypeNames.Float4).Set(Gf.Vec4f(r, g, b, 1.0))
            image.CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
            diffuse.ConnectToSource(image.ConnectableAPI(), "rgb")
        if m.get("normal_texture"):
            # A tangent-space normal map: [0, 1] texels to [-1, 1] (UsdPreviewSurface's rule).
            image = _uv_texture(stage, path, "Normal", m["normal_texture"], "raw")
            image.CreateInput("scale", Sdf.ValueTypeNames.Float4).Set(Gf.Vec4f(2, 2, 2, 1))
            image.CreateInput("bias", Sdf.ValueTypeNames.Float4).Set(Gf.Vec4f(-1, -1, -1, 0))
            image.CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
            shader.CreateInput("normal", Sdf.ValueTypeNames.Normal3f).ConnectToSource(
                image.ConnectableAPI(), "rgb"
            )
        opacity = shader.CreateInput("opacity", Sdf.ValueTypeNames.Float)
        opacity.Set(a)
        if m.get("opacity_texture"):
            # A grey opacity image (OBJ's map_d): its red channel, scaled by the alpha.
            image = _uv_texture(stage, path, "Opacity", m["opacity_texture"], "raw")
            image.CreateInput("scale", Sdf.ValueTypeNames.Float4).Set(Gf.Vec4f(a, a, a, a))
            image.CreateOutput("r", Sdf.ValueTypeNames.Float)
            opacity.ConnectToSource(image.ConnectableAPI(), "r")
        shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(float(m["roughness"]))
        shader.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(0.0)
        material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
        looks[m["name"]] = material
    return looks


def _uv_texture(stage, material_path, name, asset, colour_space):
    """A UsdUVTexture of `asset` read through the mesh's `st` (one primvar reader per
    material)."""
    reader_path = material_path + "/stReader"
    reader = UsdShade.Shader.Get(stage, reader_path)
    if not reader:
        reader = UsdShade.Shader.Define(stage, reader_path)
        reader.CreateIdAttr("UsdPrimvarReader_float2")
        reader.CreateInput("varname", Sdf.ValueTypeNames.Token).Set("st")
        reader.CreateOutput("result", Sdf.ValueTypeNames.Float2)
    image = UsdShade.Shader.Define(stage, material_path + "/" + name)
    image.CreateIdAttr("UsdUVTexture")
    image.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(asset)
    image.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set(colour_space)
    image.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(
        reader.ConnectableAPI(), "result"
    )
    return image


def _bind_materials(mesh, faces, looks, face_count):
    """Binds the mesh's materials: the whole mesh when one covers every face, else one
    GeomSubset per material (family materialBind)."""
    faces = [(name, int(start), int(count)) for name, start, count in faces if name in looks]
    if not faces:
        return
    if len(faces) == 1 and faces[0][1] == 0 and faces[0][2] == face_count:
        UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(looks[faces[0][0]])
        return
    by_name = {}
    for name, start, count in faces:
        by_name.setdefault(name, []).extend(range(start, start + count))
    for k, (name, indices) in enumerate(by_name.items()):
        subset = UsdGeom.Subset.CreateGeomSubset(
            mesh,
            "material_%d" % k,
            UsdGeom.Tokens.face,
            Vt.IntArray(indices),
            "materialBind",
            UsdGeom.Tokens.nonOverlapping,
        )
        UsdShade.MaterialBindingAPI.Apply(subset.GetPrim()).Bind(looks[name])


def write_new_stage(out_path, spec):
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z if spec["up_axis"] == "Z" else UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, float(spec["meters_per_unit"]))
    root = UsdGeom.Xform.Define(stage, "/root")
    stage.SetDefaultPrim(root.GetPrim())
    looks = _define_materials(stage, spec.get("materials"))
    frame_count = int(spec["frame_count"])
    for item in spec["meshes"]:
        xform_path = "/root/" + item["name"]
        xform = UsdGeom.Xform.Define(stage, xform_path)
        xform.AddTransformOp().Set(_matrix_from_bytes(item["world"]))
        # The mesh prim takes the object's name too: Blender's importer names the object it
        # makes of an Xform and its one Mesh after the Mesh, as it does its own exports'.
        location = xform_path + "/" + item["name"]
        mesh = UsdGeom.Mesh.Define(stage, location)
        mesh.CreateSubdivisionSchemeAttr().Set(UsdGeom.Tokens.none)
        mesh.CreateFaceVertexCountsAttr().Set(_int_array(item["counts"]))
        mesh.CreateFaceVertexIndicesAttr().Set(_int_array(item["indices"]))
        n = item["point_count"]
        # The default (untimed) value is the rest shape; the frames are time samples.
        mesh.CreatePointsAttr().Set(_vec3f_array(item["rest_points"], n))
        if item.get("uvs") is not None:
            st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
                "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex
            )
            st.Set(_vec2f_array(item["uvs"], n))
        face_count = len(memoryview(item["counts"]).cast("B")) // 4
        _bind_materials(mesh, item.get("material_faces") or [], looks, face_count)
        _author_frames(mesh, item, frame_count, location)
    _author_particles(stage, spec.get("particles"), "/root")
    _set_stage_timing(stage, spec)
    _export(stage, out_path, spec.get("texture_files"))


def _export_usdz(stage, out_path, texture_files):
    """A .usdz holding the layer and the images its asset paths name (UsdUtils packs them):
    the layer and `texture_files` (relative path, bytes) are written to a temporary folder
    first, at the relative paths the materials use."""
    import tempfile

    from pxr import UsdUtils

    with tempfile.TemporaryDirectory() as folder:
        layer = os.path.join(folder, "baked.usdc")
        for rel, data in texture_files:
            target = os.path.join(folder, rel)
            os.makedirs(os.path.dirname(target), exist_ok=True)
            with open(target, "wb") as f:
                f.write(data)
        _export(stage, layer)
        try:
            ok = UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(layer), out_path)
        except Exception as e:
            raise BridgeError("usd-core cannot write the .usdz package: " + _clean_tf_message(e))
        if not ok:
            raise BridgeError("usd-core cannot write the .usdz package")
    _clear_zip_times(out_path)


def _clear_zip_times(path):
    """Sets every entry's modification time in a zip (a .usdz) to 1980-01-01 00:00, the
    zip format's epoch: usd-core stamps the packing time, and the same bake must give the same
    bytes. Only the 4 time bytes of each local and central header change (the CRCs do not
    cover them, the 64-byte alignment stays)."""
    import struct

    with open(path, "rb") as f:
        data = bytearray(f.read())
    epoch = struct.pack("<HH", 0, (0 << 9) | (1 << 5) | 1)
    at = 0
    while at + 30 <= len(data) and data[at:at + 4] == b"PK\x03\x04":
        data[at + 10:at + 14] = epoch
        size, _, name, extra = struct.unpack_from("<IIHH", data, at + 18)
        at += 30 + name + extra + size
    while at + 46 <= len(data) and data[at:at + 4] == b"PK\x01\x02":
        data[at + 12:at + 16] = epoch
        name, extra, comment = struct.unpack_from("<HHH", data, at + 28)
        at += 46 + name + extra + comment
    with open(path, "wb") as f:
        f.write(data)

def _author_particles(stage, particles, parent):
    """One UsdGeom.Points per emitter under `parent`/particles: points, widths, ids, extent
    and the primvar displayOpacity sampled at every frame (time code = frame index), a
    particle count that changes from frame to frame; and `<emitter>_streaks` curves for an
    emitter drawn with streaks."""
    if not particles:
        return
    scope = parent.rstrip("/") + "/particles"
    UsdGeom.Scope.Define(stage, scope)
    for item in particles:
        points = UsdGeom.Points.Define(stage, scope + "/" + item["prim"])
        pts_attr = points.CreatePointsAttr()
        widths_attr = points.CreateWidthsAttr()
        ids_attr = points.CreateIdsAttr()
        extent_attr = points.CreateExtentAttr()
        opacity = UsdGeom.PrimvarsAPI(points).CreatePrimvar(
            "displayOpacity", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.vertex
        )
        points.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set(
            Vt.Vec3fArray([Gf.Vec3f(*item["colour"])])
        )
        for f, frame in enumerate(item["frames"]):
            t = Usd.TimeCode(float(f))
            n = frame["count"]
            pts = _vec3f_array(frame["positions"], n) if n else Vt.Vec3fArray()
            widths = Vt.FloatArray.FromBuffer(memoryview(frame["widths"]).cast("B").cast("f")) if n else Vt.FloatArray()
            pts_attr.Set(pts, t)
            widths_attr.Set(widths, t)
            ids_attr.Set(Vt.Int64Array.FromBuffer(memoryview(frame["ids"]).cast("B").cast("q")) if n else Vt.Int64Array(), t)
            opacity.Set(Vt.FloatArray.FromBuffer(memoryview(frame["opacities"]).cast("B").cast("f")) if n else Vt.FloatArray(), t)
            extent = UsdGeom.Points.ComputeExtent(pts, widths) if n else Vt.Vec3fArray([Gf.Vec3f(0.0), Gf.Vec3f(0.0)])
            extent_attr.Set(extent, t)
        if item.get("streaks"):
            _author_streaks(stage, scope + "/" + item["prim"] + "_streaks", item)


def _author_streaks(stage, path, item):
    """A linear BasisCurves of one segment per particle, from its streak's tail to the
    particle, as wide as the particle, sampled at every frame (a fountain's water)."""
    curves = UsdGeom.BasisCurves.Define(stage, path)
    curves.CreateTypeAttr(UsdGeom.Tokens.linear)
    curves.CreateWrapAttr(UsdGeom.Tokens.nonperiodic)
    curves.SetWidthsInterpolation(UsdGeom.Tokens.vertex)
    curves.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set(
        Vt.Vec3fArray([Gf.Vec3f(*item["colour"])])
    )
    attrs = (
        curves.CreateCurveVertexCountsAttr(),
        curves.CreatePointsAttr(),
        curves.CreateWidthsAttr(),
        curves.CreateExtentAttr(),
    )
    counts_attr, points_attr, widths_attr, extent_attr = attrs
    for f, frame in enumerate(item["frames"]):
        t = Usd.TimeCode(float(f))
        n = frame["count"]
        points = _vec3f_array(frame["streak_points"], 2 * n) if n else Vt.Vec3fArray()
        doubled = Vt.FloatArray.FromBuffer(memoryview(frame["streak_widths"]).cast("B").cast("f")) if n else Vt.FloatArray()
        counts_attr.Set(Vt.IntArray([2] * n), t)
        points_attr.Set(points, t)
        widths_attr.Set(doubled, t)
        extent = UsdGeom.Curves.ComputeExtent(points, doubled) if n else Vt.Vec3fArray([Gf.Vec3f(0.0), Gf.Vec3f(0.0)])
        extent_attr.Set(extent, t)
