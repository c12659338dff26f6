"""The VTK side of bench-peers: vtkFixedPointVolumeRayCastMapper (VTK 9.1, Debian python3-vtk9) on the
inputs sparseleap renders, run under Xvfb (Debian's VTK has only an X11 window).

Started once per case; loads the volume, sets up the mapper to match sparseleap, renders one warm-up
frame (the mapper builds its min-max space-leaping volume there), prints `RESULT {"ready": true, ...}`,
then serves commands read line by line from stdin, answering each with one `RESULT <json>` line:

  round                time Render() for every view of the path, in order (one round)
  image I PREFIX       render view I; write PREFIX_raycast.npy (the mapper's own ray-cast image) and
                       PREFIX_framebuffer.npy (the window read back): float32 RGBA, row 0 at the top

Conventions bridged to sparseleap's (README "Formats and conventions"):
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
"""
import argparse
import ctypes
import json
import re
import sys
import time

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import vtkFloatArray, vtkVersion
from vtkmodules.vtkCommonDataModel import vtkImageData, vtkPiecewiseFunction
from vtkmodules.vtkRenderingCore import (vtkColorTransferFunction, vtkRenderer, vtkRenderWindow, vtkVolume,
                                         vtkVolumeProperty)
from vtkmodules.vtkRenderingVolume import vtkFixedPointVolumeRayCastMapper
import vtkmodules.vtkRenderingOpenGL2  # noqa: F401  (the OpenGL render window)
import vtkmodules.vtkRenderingVolumeOpenGL2  # noqa: F401  (the ray-cast image display helper)

import volumes


def reply(obj):
    sys.stdout.write("RESULT " + json.dumps(obj) + "\n")
    sys.stdout.flush()


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
        self.window = vtkRenderWindow()
        self.window.SetOffScreenRendering(1)
        self.window.SetMultiSamples(0)
        self.window.SetSize(args.width, args.height)
        self.window.AddRenderer(self.renderer)
        self.width, self.height = args.width, args.height

        with open(args.path) as f:
            self.views = json.load(f)["keyframes"]

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
        t = time.perf_counter()
        self.window.Render()
        return 1000.0 * (time.perf_counter() - t), 1000.0 * self.mapper.GetTimeToDraw()

    def raycast_image(self):
        """The mapper's ray-cast image (unsigned short RGBA, 15-bit fixed point) as float RGBA, row 0 at
        the top. The Python wrapping returns the C++ pointer only as an address string, so the pixels
        are copied out with ctypes while the mapper still owns them (until the next Render())."""
        rc = self.mapper.GetRayCastImage()
        if tuple(rc.GetImageViewportSize()) != (self.width, self.height):
            raise RuntimeError(f"ray-cast image viewport {rc.GetImageViewportSize()} is not the window size")
        m = re.match(r"_([0-9a-fA-F]+)_p_", str(rc.GetImage()))
        if not m:
            raise RuntimeError(f"unexpected pointer form {rc.GetImage()!r} from vtkFixedPointRayCastImage")
        mw, mh = rc.GetImageMemorySize()
        buf = (ctypes.c_uint16 * (mw * mh * 4)).from_address(int(m.group(1), 16))
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
    args = ap.parse_args()
    args.width, args.height = (int(v) for v in args.size.split("x"))

    scene = VtkScene(args)
    for _ in range(args.warmup):
        scene.render(0)
    reply({"ready": True, "vtk": vtkVersion.GetVTKVersion(), "views": len(scene.views)})
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
