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
        "NormalMode": "Gradient", "ComputeNormals": 1, "ComputeGradients": 0, "ComputeScalars": 1,
        "ComputeLevels": 0, "InterpolateAttributes": 0, "MaxTriangles": 0,
        "NumberOfThreads": 0, "ArrayComponent": 0, "OutputPointsPrecision": "Default",
        "ReconstructionFilter": "Trilinear", "UseSMPTools": 0,
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

    # With a multi-component array, the domain (and the default value, its
    # middle) follows the selected component.
    calc = pvs.Calculator(Input=wavelet, ResultArrayName="vec",
                          Function="coordsX*iHat + RTData*jHat + 2*RTData*kHat")
    calc.UpdatePipeline()
    by_component = pvs.PreciseContour(Input=calc, ContourBy=["POINTS", "vec"], ArrayComponent=2)
    component_domain = by_component.GetProperty("ContourValues").SMProperty.GetDomain("scalar_range")
    crng = calc.PointData["vec"].GetRange(2)
    value = list(by_component.Isosurfaces)
    check("isosurfaces domain and default follow ArrayComponent",
          abs(component_domain.GetMinimum(0) - crng[0]) < 1e-3
          and abs(component_domain.GetMaximum(0) - crng[1]) < 1e-3
          and len(value) == 1 and crng[0] < value[0] < crng[1],
          f"{component_domain.GetMinimum(0)}..{component_domain.GetMaximum(0)}, default {value}, "
          f"component 2 range {crng}")
    by_component.UpdatePipeline()
    check("contours the selected component at its default value",
          by_component.GetDataInformation().GetNumberOfCells() > 1000,
          f"{by_component.GetDataInformation().GetNumberOfCells()} triangles")
    pvs.Delete(by_component)
    pvs.Delete(calc)

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
    check("no gradients by default", "Gradients" not in arrays[0], f"{arrays}")
    contour.ComputeGradients = 1
    contour.UpdatePipeline()
    gradients = contour.PointData.keys()
    check("Compute Gradients adds the Gradients array",
          "Gradients" in gradients
          and contour.PointData["Gradients"].GetNumberOfComponents() == 3, f"{gradients}")
    contour.ComputeGradients = 0

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

    # The reconstruction filters: each reaches the VTK filter (a cubic one
    # moves the split points, so the surface differs from the trilinear one)
    # and is listed in the property's enumeration, in the refinement group.
    contour.Topology = "Trilinear"
    contour.Rule = "A1"
    contour.Epsilon = 0.01
    contour.MaxLevel = 2
    prop = contour.GetProperty("ReconstructionFilter").SMProperty
    entries = prop.GetDomain("enum")
    texts = [entries.GetEntryText(i) for i in range(entries.GetNumberOfEntries())]
    values = [entries.GetEntryValue(i) for i in range(entries.GetNumberOfEntries())]
    check("ReconstructionFilter enumeration",
          texts == ["Trilinear", "Catmull-Rom", "B-Spline", "B-Spline Interpolating"]
          and values == [0, 1, 2, 3], f"{texts} {values}")
    bounds = {}
    for text in texts:
        contour.ReconstructionFilter = text
        contour.UpdatePipeline()
        info = contour.GetDataInformation()
        bounds[text] = (info.GetNumberOfCells(), info.GetBounds())
    differ = [t for t in texts[1:] if bounds[t] != bounds["Trilinear"] and bounds[t][0] > 0]
    check("reconstruction filters change the surface", differ == texts[1:], f"{bounds}")
    # The plugin's classes are not Python-wrapped: read the VTK filter's
    # PrintSelf.
    printed = str(contour.GetClientSideObject())
    check("ReconstructionFilter reaches the VTK filter",
          "ReconstructionFilter: BSplineInterpolating" in printed,
          [line for line in printed.splitlines() if "Reconstruction" in line])
    groups = [g for g in range(contour.SMProxy.GetNumberOfPropertyGroups())
              if contour.SMProxy.GetPropertyGroup(g).GetXMLLabel() == "Topology and Refinement"]
    group = contour.SMProxy.GetPropertyGroup(groups[0]) if groups else None
    members = [group.GetProperty(i) for i in range(group.GetNumberOfProperties())] if group else []
    check("ReconstructionFilter in the refinement group", prop in members, f"{groups}")

    print(f"load: {sum(checks)} passed, {len(checks) - sum(checks)} failed")


main()
