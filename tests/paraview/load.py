"""The plugin loads and its proxy works (run by pvbatch and by pvpython).

    pvbatch load.py PLUGIN
    pvpython load.py PLUGIN

Prints "ok <check>" or "FAIL <check>: <why>" per check.
"""
import os
import sys

# pvpython puts the folder of the system's vtkmodules (python3-vtk9 on
# Debian 12) before PYTHONPATH; ParaView's own modules must come first.
if os.environ.get("PYTHONPATH"):
    sys.path[:0] = [p for p in os.environ["PYTHONPATH"].split(os.pathsep) if p]

import paraview.simple as pvs  # noqa: E402

checks = []


def check(name, condition, why=""):
    checks.append(bool(condition))
    print(("ok " if condition else "FAIL ") + name + ("" if condition else ": " + why))
    sys.stdout.flush()


def main():
    pvs.LoadPlugin(sys.argv[1], remote=False, ns=pvs.__dict__)
    check("proxy PreciseContour defined", hasattr(pvs, "PreciseContour"))

    wavelet = pvs.Wavelet()
    contour = pvs.PreciseContour(Input=wavelet, ContourBy=["POINTS", "RTData"])
    defaults = {
        "Epsilon": 0.01, "MaxLevel": 5, "Rule": "A1", "Topology": "Trilinear",
        "NormalMode": "Gradient", "ComputeNormals": 1, "ComputeScalars": 1,
        "ComputeLevels": 0, "InterpolateAttributes": 0, "MaxTriangles": 0,
        "NumberOfThreads": 0, "ArrayComponent": 0, "OutputPointsPrecision": "Default",
    }
    wrong = {k: contour.GetPropertyValue(k) for k, v in defaults.items()
             if contour.GetPropertyValue(k) != v}
    check("property defaults", not wrong, f"{wrong}")

    # Every property has a domain and documentation.
    missing = []
    for name in contour.ListProperties():
        prop = contour.GetProperty(name).SMProperty
        if name != "Input" and prop.GetNumberOfDomains() == 0:
            missing.append(name + " (domain)")
        if prop.GetDocumentation() is None:
            missing.append(name + " (documentation)")
    check("domains and documentation", not missing, ", ".join(missing))

    # The contour values' domain is the range of the selected array.
    contour.UpdatePipelineInformation()
    domain = contour.GetProperty("ContourValues").SMProperty.GetDomain("scalar_range")
    rng = wavelet.PointData["RTData"].GetRange()
    check("isosurfaces domain is the data range",
          domain.GetMinimumExists(0) and domain.GetMaximumExists(0)
          and abs(domain.GetMinimum(0) - rng[0]) < 1e-6 and abs(domain.GetMaximum(0) - rng[1]) < 1e-6,
          f"{domain.GetMinimum(0)}..{domain.GetMaximum(0)} vs {rng}")

    contour.Isosurfaces = [157.0]
    contour.ComputeLevels = 1
    contour.UpdatePipeline()
    info = contour.GetDataInformation()
    refined = info.GetNumberOfCells()
    check("contours the Wavelet", refined > 1000, f"{refined} triangles")
    arrays = [contour.PointData.keys(), contour.CellData.keys()]
    check("output arrays", "Normals" in arrays[0] and "RTData" in arrays[0]
          and "RefinementLevel" in arrays[1], f"{arrays}")
    levels = contour.CellData["RefinementLevel"].GetRange()
    check("refinement happened", levels[1] >= 1, f"levels {levels}")

    contour.Epsilon = 0.0
    contour.UpdatePipeline()
    plain = contour.GetDataInformation().GetNumberOfCells()
    check("Epsilon 0 gives plain Marching Cubes", 0 < plain < refined, f"{plain} vs {refined}")

    contour.Epsilon = 0.01
    contour.MaxTriangles = plain + 10
    contour.UpdatePipeline()
    capped = contour.GetDataInformation().GetNumberOfCells()
    check("MaxTriangles caps the output", plain <= capped <= plain + 10, f"{capped}")

    contour.MaxTriangles = 0
    contour.Topology = "Classic"
    contour.Rule = "B"
    contour.NormalMode = "Central Difference"
    contour.NumberOfThreads = 1
    contour.UpdatePipeline()
    check("enumerations accepted", contour.GetDataInformation().GetNumberOfCells() > 0)

    print(f"load: {sum(checks)} passed, {len(checks) - sum(checks)} failed")


main()
