#!/usr/bin/env python3
"""Renders the Marschner-Lobb surfaces of `cargo run --release --example
filters` side by side, coloured by the distance of each triangle to the
analytic isosurface (its largest sample distance, in cells), with one
shared colour bar.

Usage (Debian's VTK; off-screen rendering needs a display):
    cargo run --release --example filters          # writes target/filters/*.vtk
    scripts/with-xvfb.sh /usr/bin/python3 bench/filters_pictures.py [IN_DIR] [OUT_PNG]
Defaults: target/filters and bench/results/filters_ml.png.
"""

import os
import sys

import vtk

PANELS = [
    ("ml_mc.vtk", "Marching Cubes"),
    ("ml_trilinear.vtk", "trilinear"),
    ("ml_catmull_rom.vtk", "Catmull-Rom"),
    ("ml_bspline_interpolating.vtk", "B-spline interpolating"),
]
# Colour range in cells (values above are drawn in the top colour).
RANGE = (0.0, 0.4)
SIZE = (900, 270)


def lookup_table():
    """A viridis-like ramp, 256 entries."""
    ctf = vtk.vtkColorTransferFunction()
    stops = [
        (0.0, (0.267, 0.005, 0.329)),
        (0.25, (0.231, 0.322, 0.545)),
        (0.5, (0.129, 0.569, 0.549)),
        (0.75, (0.369, 0.788, 0.384)),
        (1.0, (0.993, 0.906, 0.144)),
    ]
    for t, (r, g, b) in stops:
        ctf.AddRGBPoint(RANGE[0] + t * (RANGE[1] - RANGE[0]), r, g, b)
    lut = vtk.vtkLookupTable()
    lut.SetNumberOfTableValues(256)
    lut.SetRange(*RANGE)
    for i in range(256):
        v = RANGE[0] + (RANGE[1] - RANGE[0]) * i / 255.0
        lut.SetTableValue(i, *ctf.GetColor(v), 1.0)
    lut.SetUseAboveRangeColor(False)
    lut.Build()
    return lut


def main():
    in_dir = sys.argv[1] if len(sys.argv) > 1 else "target/filters"
    out = sys.argv[2] if len(sys.argv) > 2 else "bench/results/filters_ml.png"
    lut = lookup_table()
    window = vtk.vtkRenderWindow()
    window.SetOffScreenRendering(1)
    window.SetSize(*SIZE)
    window.SetMultiSamples(4)
    n = len(PANELS)
    bar_width = 0.07
    camera = None
    for i, (name, title) in enumerate(PANELS):
        reader = vtk.vtkPolyDataReader()
        reader.SetFileName(os.path.join(in_dir, name))
        reader.Update()
        mesh = reader.GetOutput()
        triangles = mesh.GetNumberOfCells()
        mapper = vtk.vtkPolyDataMapper()
        mapper.SetInputData(mesh)
        mapper.SetScalarModeToUseCellData()
        mapper.SetLookupTable(lut)
        mapper.UseLookupTableScalarRangeOn()
        actor = vtk.vtkActor()
        actor.SetMapper(mapper)
        actor.GetProperty().SetInterpolationToFlat()
        actor.GetProperty().SetAmbient(0.25)
        actor.GetProperty().SetDiffuse(0.8)
        ren = vtk.vtkRenderer()
        w = (1.0 - bar_width) / n
        ren.SetViewport(i * w, 0.0, (i + 1) * w, 1.0)
        ren.SetBackground(1.0, 1.0, 1.0)
        ren.AddActor(actor)
        text = vtk.vtkTextActor()
        text.SetInput("%s\n%d triangles" % (title, triangles))
        text.GetTextProperty().SetColor(0.0, 0.0, 0.0)
        text.GetTextProperty().SetFontSize(13)
        text.SetPosition(8, 8)
        ren.AddViewProp(text)
        if camera is None:
            ren.ResetCamera()
            camera = ren.GetActiveCamera()
            # Oblique view from above, looking along +y.
            camera.Elevation(-50.0)
            camera.OrthogonalizeViewUp()
            camera.Zoom(1.35)
            ren.ResetCameraClippingRange()
        else:
            ren.SetActiveCamera(camera)
        window.AddRenderer(ren)
    bar_ren = vtk.vtkRenderer()
    bar_ren.SetViewport(1.0 - bar_width, 0.0, 1.0, 1.0)
    bar_ren.SetBackground(1.0, 1.0, 1.0)
    bar = vtk.vtkScalarBarActor()
    bar.SetLookupTable(lut)
    bar.SetTitle("cells")
    bar.SetNumberOfLabels(5)
    bar.SetLabelFormat("%.1f")
    bar.GetTitleTextProperty().SetColor(0.0, 0.0, 0.0)
    bar.GetLabelTextProperty().SetColor(0.0, 0.0, 0.0)
    bar.GetPositionCoordinate().SetCoordinateSystemToNormalizedViewport()
    bar.GetPositionCoordinate().SetValue(0.05, 0.08)
    bar.SetWidth(0.8)
    bar.SetHeight(0.84)
    bar_ren.AddViewProp(bar)
    window.AddRenderer(bar_ren)
    window.Render()
    grab = vtk.vtkWindowToImageFilter()
    grab.SetInput(window)
    grab.Update()
    writer = vtk.vtkPNGWriter()
    writer.SetFileName(out)
    writer.SetInputConnection(grab.GetOutputPort())
    writer.Write()
    print("wrote %s (%d bytes)" % (out, os.path.getsize(out)))


if __name__ == "__main__":
    main()
