"""Renders the Precise Contour of a distributed Wavelet, coloured by rank.

    xvfb-run -a mpiexec -n 2 pvbatch paraview/screenshot.py PLUGIN OUT.png

Each rank contours its piece of the volume; the pieces meet without a gap.
(docs/paraview.png was made with this script.)
"""
import os
import sys

import paraview.simple as pvs

plugin, out = sys.argv[1], sys.argv[2]
pvs.LoadPlugin(plugin, remote=False, ns=pvs.__dict__)

wavelet = pvs.Wavelet(WholeExtent=[-20, 20, -20, 20, -20, 20])
contour = pvs.PreciseContour(
    Input=wavelet,
    ContourBy=["POINTS", "RTData"],
    Isosurfaces=[160.0],
    Epsilon=0.01,
    MaxLevel=5,
    NumberOfThreads=1,
)
ranks = pvs.ProcessIdScalars(Input=contour)

view = pvs.CreateView("RenderView")
view.ViewSize = [800, 600]
view.OrientationAxesVisibility = 0
view.Background = [1.0, 1.0, 1.0]
try:  # ParaView 5.11: the background is a palette colour unless told not
    view.UseColorPaletteForBackground = 0
except AttributeError:
    pass

display = pvs.Show(ranks, view)
pvs.ColorBy(display, ("POINTS", "ProcessId"))
lut = pvs.GetColorTransferFunction("ProcessId")
lut.InterpretValuesAsCategories = 1
lut.ApplyPreset("Brewer Qualitative Set1", True)
count = int(ranks.PointData["ProcessId"].GetRange()[1]) + 1
lut.Annotations = sum(([str(r), f"rank {r}"] for r in range(count)), [])
bar = pvs.GetScalarBar(lut, view)
bar.Title = "Piece"
bar.ComponentTitle = ""
bar.TitleColor = bar.LabelColor = [0.1, 0.1, 0.1]
display.SetScalarBarVisibility(view, True)

outline = pvs.Show(pvs.Outline(Input=wavelet), view)
outline.AmbientColor = outline.DiffuseColor = [0.3, 0.3, 0.3]

view.CameraPosition = [95.0, -70.0, 60.0]
view.CameraFocalPoint = [0.0, 0.0, 0.0]
view.CameraViewUp = [0.0, 0.0, 1.0]
view.ResetCamera()
pvs.Render(view)
saved = pvs.SaveScreenshot(out, view, ImageResolution=[800, 600], CompressionLevel="9")
if saved and os.path.getsize(out) > 10000 and count > 1:
    print(f"ok screenshot of {count} pieces written to {out}")
else:
    print(f"FAIL screenshot: saved {saved}, {count} piece(s)")
