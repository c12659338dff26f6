"""The VTK side of bench-peers: vtkFixedPointVolumeRayCastMapper (VTK 9.1, Debian python3-vtk9) on the
inputs sparseleap renders, run under Xvfb (Debian's VTK has only an X11 window).

Started once per case; loads the volume, sets up the mapper to match sparseleap, renders one warm-up
frame (the mapper builds its min-max space-leaping volume there), prints `RESULT {"ready": true, ...}`,
then serves commands read line by line from stdin, answering each with one `RESULT <json>` line
(with --shade the ready line also reports the light set-up, for bench-peers to check):

  round                time Render() for every view of the path, in order (one round)
  image I PREFIX       render view I; write PREFIX_raycast.npy (the mapper's own ray-cast image) and
                       PREFIX_framebuffer.npy (the window read back): float32 RGBA, row 0 at the top

Conventions bridged to sparseleap's (docs/formats.md, "Conventions and file formats"):
- voxel centres and the volume box: VTK puts voxel i at origin + i * spacing and ends its volume at the
  outer voxel centres; sparseleap puts voxel i at (i + 0.5) * spacing and its box at [0, dims * spacing],
  sampling the outer half voxel from the edge voxels (clamp). So VTK gets the volume padded by one edge
  voxel, origin -0.5 * spacing, cropped to [0, dims * spacing]; world coordinates (camera, path) are then
  sparseleap's unchanged. Bridging only the centres (origin 0.5 * spacing, no padding) leaves rays
  half a voxel shorter at every face: 39.7 instead of 50.3 dB on neurites at 512^2 (tubes cut by the
  faces), 41.2 instead of 48.5 dB on the MRI;
- opacity: sparseleap corrects alpha per sample as 1 - (1 - a)^(dt / min spacing); VTK as
  1 - (1 - a)^(SampleDistance / ScalarOpacityUnitDistance), so the unit distance is the min spacing;
- transfer function: the same piecewise-linear points as colour (RGB space) and scalar opacity functions;
  VTK samples them at every integer value of the data range (u8: the 256 values), sparseleap into a
  4096-entry table: equal at the control points, linear between;
- camera: eye, center, up, vertical fov -> SetPosition, SetFocalPoint, SetViewUp, SetViewAngle; both cast
  one ray through each pixel centre;
- colour: the ray-cast image is premultiplied RGBA in 15-bit fixed point, like sparseleap's EXR.

Why the ray-cast image and not the framebuffer: the mapper draws its image into the window as a
texture (vtkRayCastImageDisplayHelper), and that draw shifts and blurs it by a fraction of a pixel and
quantizes it to 8 bits. On neurites at 512^2 the PSNR against sparseleap is 50.3 dB for the ray-cast
image and 32.9 dB for the framebuffer; a least-squares 3x3 kernel fitted from sparseleap's image to
VTK's has centre weight 0.997 for the ray-cast image, 0.66 for the framebuffer (the rest mostly on the
left and lower neighbours). Both are read and compared; the ray-cast image is what the ray caster
computed.

What still differs: VTK spaces a ray's samples from its near-plane point, sparseleap from its volume
entry (another phase of the same 0.5-voxel grid), VTK rounds each interpolated scalar up to an
integer table index (0x7fff added before the 15-bit shift), and VTK computes in 15-bit fixed point.

Early ray termination: the composite helpers stop a ray once its remaining opacity, in 15-bit fixed
point, drops below 0xff (VTKKWRCHelper_CompositeColorAndCheckEarlyTermination), i.e. at accumulated
opacity 1 - 255/32767 = 0.9922; there is no switch to turn this off, so bench-peers runs sparseleap
with --ert (0.99).

Shading (--shade, with --ambient/--diffuse/--specular/--shininess as given to `sparseleap --shade`):
ShadeOn() and the same Ka, Kd, Ks and specular power on the volume property. sparseleap's model
(core/cast/shading.h, applied in core/cast/raycast.h take_sample to the straight transfer-function colour, then
premultiplied by the sample's opacity) is rgb * (Ka + Kd |n.l|) + Ks |n.l|^P, white, with a headlight
(l = the ray's direction), two-sided, n = the central difference of the trilinear reconstruction one
voxel apart, normalized; a sample whose gradient is ~0 keeps its unlit rgb. How the fixed-point mapper
shades (vtkFixedPointVolumeRayCastMapper, vtkEncodedGradientShader, VTKKWRCHelper_InterpolateShading):
- gradients: computed once per volume at the voxels (central differences on the grid, one-sided at the
  padded edge, scaled by the spacing); the direction is encoded in 16 bits (vtkSphericalDirectionEncoder,
  65536 directions; measured error 0.4 deg mean, 1.0 deg max), the magnitude in 8 bits, used only for
  gradient opacity (off here: its function is the constant 1). A voxel whose three differences are all
  exactly 0 gets the "zero normal";
- shading tables: before each frame, one diffuse and one specular value per encoded direction, summed
  over the renderer's lights: diffuse = Ka I ambient colour + Kd I max(n.l, 0) diffuse colour, specular
  = Ks I (n.h)^P specular colour where n.l > 0 and n.h > 0.001, with two-sided lighting flipping normals
  that face away from the viewer; the zero normal gets Ka I ambient colour + ZeroNormalDiffuseIntensity
  Kd I (default 0, clamped to [0, 1], and the mapper's gradient shader has no accessor in 9.1), no
  specular; stored in 15-bit fixed point. Every light is taken as directional, and the view direction
  is the camera's central one: l and h are the same for every pixel;
- per sample: the table values of the cell's eight corners' encoded normals are interpolated with the
  sample's trilinear weights into D and S, and the premultiplied colour becomes D * (a rgb) + S * a:
  shading before the opacity weighting, as in sparseleap.
Bridged here (function headlight() and VtkScene.unlit_zero_normal()):
- the light: the renderer's own light (created on the first Render() when it has none) is a headlight
  of intensity 1 but with vtkLight's default black ambient colour, which drops the Ka term; so one
  explicit white headlight, intensity 1 (ambient, diffuse and specular colours white), two-sided
  lighting, the renderer's automatic light creation off. It follows the camera (LightFollowCamera).
  With the headlight h = l (half vector of l and the view), so VTK's specular is Ks (n.l)^P, as ours;
- the zero normal (only with --zero-normal unlit, bench-peers' --vtk-zero-normal unlit, a diagnostic;
  by default VTK keeps its own rule): sparseleap's rule (unlit rgb) instead of VTK's ambient-only Ka rgb, by setting the
  zero normal's diffuse entries to 1.0 after the mapper built the tables and before it casts rays
  (observer of VolumeMapperRenderStartEvent, every frame; checked). It matters where the data are flat
  inside visible structures: zero normals are 17 % of the opacity-weighted visible voxels of neurites
  (tube interiors), 3 % of blobs (the 255 plateaus), 0.2 % of the MRI.
What still differs, and can't be bridged by inputs (PSNR, view 0 at 256^2, sparseleap vs VTK):
                                                   neurites   MRI    blobs
  unshaded                                           50.0     48.3   51.1
  shaded, the renderer's default light                 27.6     30.6   31.3
  + the explicit white headlight (the default run)     30.8     34.3   36.4
  + the zero normal unlit (the diagnostic patch)       35.5     34.2   42.4
  + both cameras orthographic (a diagnostic only)      36.2     39.0   49.9
- light direction: VTK's is the central view direction for the whole image, sparseleap's each ray's
  (a light at the eye); with the 30 deg field of view they part by up to about 21 deg in the corners.
  That costs the MRI (a large, curved, lit surface) about 5 dB and blobs 7 dB; with orthographic
  cameras, where the two coincide, blobs reach 49.9 dB, close to unshaded;
- shading interpolation: sparseleap interpolates the gradient and shades once (its central difference
  of the trilinear reconstruction is, in the interior, exactly the trilinear interpolation of the voxel
  differences VTK uses, but not normalized per voxel), VTK normalizes per voxel, shades per voxel and
  interpolates the shading. These agree where the normal varies slowly over a cell (blobs) and not where
  it turns within a cell: the thin neurite tubes (1-3 voxels across), whose corners mix zero normals
  with surface normals (sparseleap then shades with the surface normal, VTK blends unlit and shaded),
  and the noisy MRI, where per-voxel normals of small differences are nearly random and the shading of
  their average is not the average of their shadings. Sampled at random points in each volume, the
  opacity-weighted RMS difference of the diffuse factor Ka + Kd |n.l| between the two rules is 0.17
  (neurites), 0.10 (MRI), 0.035 (blobs);
- normal quantization (<= 1 deg) and the 15-bit tables: small beside the above.
"""
import argparse
import ctypes
import json
import re
import sys
import time

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import vtkCommand, vtkFloatArray, vtkVersion
from vtkmodules.vtkCommonDataModel import vtkImageData, vtkPiecewiseFunction
from vtkmodules.vtkRenderingCore import (vtkColorTransferFunction, vtkLight, vtkRenderer, vtkRenderWindow,
                                         vtkVolume, vtkVolumeProperty)
from vtkmodules.vtkRenderingVolume import vtkFixedPointVolumeRayCastMapper, vtkSphericalDirectionEncoder
import vtkmodules.vtkRenderingOpenGL2  # noqa: F401  (the OpenGL render window)
import vtkmodules.vtkRenderingVolumeOpenGL2  # noqa: F401  (the ray-cast image display helper)

import volumes


# The mapper's fixed-point scale (VTKKW_FP_SCALE): 1.0 in its colour, opacity and shading tables.
FP_ONE = 32767


def address(pointer, what):
    """The address in a pointer the Python wrapping returns as a string ('_7f05ee0fbbd0_p_void')."""
    m = re.match(r"_([0-9a-fA-F]+)_p_", str(pointer))
    if not m or int(m.group(1), 16) == 0:
        raise RuntimeError(f"unexpected pointer form {pointer!r} for {what}")
    return int(m.group(1), 16)


def reply(obj):
    sys.stdout.write("RESULT " + json.dumps(obj) + "\n")
    sys.stdout.flush()


def headlight(renderer):
    """sparseleap's light on `renderer`: one white headlight of intensity 1, two-sided lighting, and no
    other light (the renderer would create its own headlight on the first Render(), with a black
    ambient colour)."""
    renderer.AutomaticLightCreationOff()
    renderer.RemoveAllLights()
    light = vtkLight()
    light.SetLightTypeToHeadlight()  # moved to the camera's position and focal point before every frame
    light.PositionalOff()
    light.SetIntensity(1.0)
    # vtkLight's ambient colour defaults to black (SetColor sets only diffuse and specular), which would
    # drop the ambient term Ka * ambient colour * intensity; sparseleap's is Ka (white).
    light.SetAmbientColor(1.0, 1.0, 1.0)
    light.SetDiffuseColor(1.0, 1.0, 1.0)
    light.SetSpecularColor(1.0, 1.0, 1.0)
    renderer.AddLight(light)
    renderer.LightFollowCameraOn()
    renderer.TwoSidedLightingOn()
    return light


class VtkScene:
    def __init__(self, args):
        arr, spacing = volumes.read_volume(args.volume)
        # One voxel of edge padding (sparseleap's clamp to the edge voxels) with its first voxel centre at
        # -0.5 * spacing puts voxel i's centre at (i + 0.5) * spacing, and a cropping box at sparseleap's
        # volume box [0, dims * spacing] makes rays enter and leave where sparseleap's do.
        self.arr = np.pad(arr, 1, mode="edge")  # vtkImageData keeps a pointer into it
        img = vtkImageData()
        img.SetDimensions(self.arr.shape[2], self.arr.shape[1], self.arr.shape[0])
        img.SetSpacing(*spacing)
        img.SetOrigin(*[-0.5 * s for s in spacing])
        img.GetPointData().SetScalars(numpy_support.numpy_to_vtk(self.arr.ravel(), deep=False))
        self.img = img
        box = [0.0, arr.shape[2] * spacing[0], 0.0, arr.shape[1] * spacing[1], 0.0, arr.shape[0] * spacing[2]]

        with open(args.tf) as f:
            tf = json.load(f)
        color, opacity = vtkColorTransferFunction(), vtkPiecewiseFunction()
        color.SetColorSpaceToRGB()
        for p in tf["points"]:
            r, g, b, a = p["rgba"]
            color.AddRGBPoint(p["value"], r, g, b)
            opacity.AddPoint(p["value"], a)
        prop = vtkVolumeProperty()
        prop.SetColor(color)
        prop.SetScalarOpacity(opacity)
        prop.SetInterpolationTypeToLinear()
        if args.shade:
            prop.ShadeOn()
            prop.SetAmbient(args.ambient)
            prop.SetDiffuse(args.diffuse)
            prop.SetSpecular(args.specular)
            prop.SetSpecularPower(args.shininess)
        else:
            prop.ShadeOff()
        prop.SetScalarOpacityUnitDistance(min(spacing))

        mapper = vtkFixedPointVolumeRayCastMapper()
        mapper.SetInputData(img)
        mapper.SetBlendModeToComposite()
        mapper.SetSampleDistance(args.step * min(spacing))
        mapper.AutoAdjustSampleDistancesOff()
        mapper.LockSampleDistanceToInputSpacingOff()
        mapper.SetImageSampleDistance(1.0)
        mapper.IntermixIntersectingGeometryOff()
        mapper.SetNumberOfThreads(args.threads)
        # Subvolume cropping (flags 0x2000) only clips each ray to the box, no per-sample test.
        mapper.CroppingOn()
        mapper.SetCroppingRegionFlagsToSubVolume()
        mapper.SetCroppingRegionPlanes(*box)
        self.mapper = mapper

        volume = vtkVolume()
        volume.SetMapper(mapper)
        volume.SetProperty(prop)
        self.renderer = vtkRenderer()
        self.renderer.SetBackground(0.0, 0.0, 0.0)
        self.renderer.AddVolume(volume)
        self.zero_normal_patches = 0
        self.patch_zero_normal = args.shade and args.zero_normal == "unlit"
        if args.shade:
            self.light = headlight(self.renderer)
            if self.patch_zero_normal:
                self.ambient = args.ambient
                encoder = vtkSphericalDirectionEncoder()  # the mapper's own (built in its constructor)
                self.zero_normal = encoder.GetEncodedDirection((0.0, 0.0, 0.0))
                self.directions = encoder.GetNumberOfEncodedDirections()
                mapper.AddObserver(vtkCommand.VolumeMapperRenderStartEvent, self.unlit_zero_normal)
        self.window = vtkRenderWindow()
        self.window.SetOffScreenRendering(1)
        self.window.SetMultiSamples(0)
        self.window.SetSize(args.width, args.height)
        self.window.AddRenderer(self.renderer)
        self.width, self.height = args.width, args.height

        with open(args.path) as f:
            self.views = json.load(f)["keyframes"]

    def unlit_zero_normal(self, *_):
        """Observer of VolumeMapperRenderStartEvent, sent by the mapper each frame after it rebuilt its
        shading tables (PerVolumeInitialization) and before the threads cast rays: the zero normal's
        diffuse entries become 1.0 (its specular ones are 0), so a sample whose eight corners all have a
        zero gradient keeps its unlit colour, as sparseleap's does (core/cast/shading.h), instead of VTK's
        ambient-only Ka. See "Shading" in the module docstring."""
        n = 3 * self.directions
        table = np.ctypeslib.as_array((ctypes.c_uint16 * n).from_address(
            address(self.mapper.GetDiffuseShadingTable(0), "the diffuse shading table")))
        entry = table[3 * self.zero_normal:3 * self.zero_normal + 3]
        expected = int(self.ambient * FP_ONE + 0.5)  # vtkEncodedGradientShader: Ka * white ambient
        if not (np.all(entry == expected) or np.all(entry == FP_ONE)):
            raise RuntimeError(f"zero-normal shading entry {entry.tolist()} is not Ka = {expected}: "
                               "unexpected shading table layout")
        entry[:] = FP_ONE
        self.zero_normal_patches += 1

    def set_view(self, i):
        v = self.views[i]
        cam = self.renderer.GetActiveCamera()
        cam.SetPosition(*v["eye"])
        cam.SetFocalPoint(*v["center"])
        cam.SetViewUp(*v["up"])
        cam.SetViewAngle(v.get("fov_deg", 30.0))
        self.renderer.ResetCameraClippingRange()

    def render(self, i):
        """Milliseconds of Render() for view i (wall clock), and the mapper's own draw time."""
        self.set_view(i)
        patches = self.zero_normal_patches
        t = time.perf_counter()
        self.window.Render()
        ms = 1000.0 * (time.perf_counter() - t)
        # VTK only prints an exception raised in an observer, so a failed patch is caught here.
        if self.patch_zero_normal and self.zero_normal_patches != patches + 1:
            raise RuntimeError("the zero-normal shading entry was not patched in this frame (see the log)")
        return ms, 1000.0 * self.mapper.GetTimeToDraw()

    def raycast_image(self):
        """The mapper's ray-cast image (unsigned short RGBA, 15-bit fixed point) as float RGBA, row 0 at
        the top. The Python wrapping returns the C++ pointer only as an address string, so the pixels
        are copied out with ctypes while the mapper still owns them (until the next Render())."""
        rc = self.mapper.GetRayCastImage()
        if tuple(rc.GetImageViewportSize()) != (self.width, self.height):
            raise RuntimeError(f"ray-cast image viewport {rc.GetImageViewportSize()} is not the window size")
        mw, mh = rc.GetImageMemorySize()
        buf = (ctypes.c_uint16 * (mw * mh * 4)).from_address(address(rc.GetImage(), "vtkFixedPointRayCastImage"))
        pix = np.ctypeslib.as_array(buf).reshape(mh, mw, 4).astype(np.float32) / 32767.0
        ox, oy = rc.GetImageOrigin()
        uw, uh = rc.GetImageInUseSize()
        full = np.zeros((self.height, self.width, 4), np.float32)
        full[oy:oy + uh, ox:ox + uw] = pix[:uh, :uw]  # VTK's row 0 is the bottom
        return full[::-1].copy()

    def framebuffer_image(self):
        arr = vtkFloatArray()
        self.window.GetRGBAPixelData(0, 0, self.width - 1, self.height - 1, 0, arr)
        return numpy_support.vtk_to_numpy(arr).reshape(self.height, self.width, 4)[::-1].copy()


def main():
    ap = argparse.ArgumentParser(description="VTK worker of bench-peers (commands on stdin)")
    ap.add_argument("--volume", required=True, help="NRRD file or OME-Zarr store")
    ap.add_argument("--tf", required=True, help="sparseleap transfer function JSON")
    ap.add_argument("--path", required=True, help="sparseleap camera path JSON (one keyframe per view)")
    ap.add_argument("--size", required=True, help="WxH")
    ap.add_argument("--step", type=float, default=0.5, help="sample distance in units of the min spacing")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--warmup", type=int, default=1, help="unrecorded frames before the first round")
    ap.add_argument("--shade", action="store_true", help="Blinn-Phong, one headlight (as sparseleap --shade)")
    ap.add_argument("--ambient", type=float, default=0.1)
    ap.add_argument("--diffuse", type=float, default=0.7)
    ap.add_argument("--specular", type=float, default=0.2)
    ap.add_argument("--shininess", type=float, default=10.0, help="specular power")
    ap.add_argument("--zero-normal", choices=("unlit", "ambient"), default="unlit",
                    help="--shade: a zero gradient keeps the unlit colour (sparseleap's rule, the shading table "
                         "patched) or gets VTK's own ambient-only shading")
    args = ap.parse_args()
    args.width, args.height = (int(v) for v in args.size.split("x"))

    scene = VtkScene(args)
    for _ in range(args.warmup):
        scene.render(0)
    ready = {"ready": True, "vtk": vtkVersion.GetVTKVersion(), "views": len(scene.views)}
    if args.shade:
        lights = scene.renderer.GetLights()
        light = scene.light
        ready["lighting"] = {"lights": lights.GetNumberOfItems(), "headlight": bool(light.LightTypeIsHeadlight()),
                             "intensity": light.GetIntensity(), "ambient_color": light.GetAmbientColor(),
                             "diffuse_color": light.GetDiffuseColor(), "specular_color": light.GetSpecularColor(),
                             "two_sided": bool(scene.renderer.GetTwoSidedLighting()),
                             "shading_required": bool(scene.mapper.GetShadingRequired()),
                             "zero_normal": args.zero_normal, "zero_normal_patches": scene.zero_normal_patches}
    reply(ready)
    for line in sys.stdin:
        cmd = line.split()
        if not cmd:
            continue
        if cmd[0] == "round":
            times = [scene.render(i) for i in range(len(scene.views))]
            reply({"frame_ms": [t[0] for t in times], "mapper_ms": [t[1] for t in times]})
        elif cmd[0] == "image" and len(cmd) == 3:
            scene.render(int(cmd[1]))
            np.save(cmd[2] + "_raycast.npy", scene.raycast_image())
            np.save(cmd[2] + "_framebuffer.npy", scene.framebuffer_image())
            reply({"image": cmd[2]})
        else:
            reply({"error": f"unknown command {line.strip()!r}"})


if __name__ == "__main__":
    main()
