/*=========================================================================

  Program:   PreciseMC
  Module:    TestPreciseMarchingCubesPipeline.cxx

  Pipeline behaviour of vtkPreciseMarchingCubes: an unchanged pipeline does
  not re-execute and a changed property (or contour value) does; aborting
  from a ProgressEvent observer stops the run with an empty output; errors
  (no scalars, bad ArrayComponent, NaN epsilon, unsupported dimension) are
  reported through vtkErrorMacro with an empty output, and the filter works
  again afterwards; contour values changed by an observer during a run
  apply from the next run. UseSMPTools gives the same output on every vtkSMPTools
  backend. PrintSelf runs.

=========================================================================*/
#include "vtkPreciseMarchingCubes.h"

#include "PreciseMCTestUtilities.h"

#include "vtkRTAnalyticSource.h"
#include "vtkSMPTools.h"

#include <cstdlib>
#include <new>
#include <stdexcept>
#include <sstream>

namespace
{

int Failures = 0;

void Check(bool condition, const std::string& what)
{
  std::cout << (condition ? "ok " : "FAIL ") << what << "\n";
  if (!condition)
  {
    ++Failures;
  }
}

// Sets the filter's abort flag at the first progress event.
class AbortOnProgress : public vtkCommand
{
public:
  static AbortOnProgress* New() { return new AbortOnProgress; }
  void Execute(vtkObject* caller, unsigned long, void* callData) override
  {
    ++this->Calls;
    const double progress = callData ? *static_cast<double*>(callData) : 0.0;
    if (this->Enabled && progress > 0.0)
    {
      static_cast<vtkAlgorithm*>(caller)->SetAbortExecute(1);
    }
  }
  bool Enabled = true;
  int Calls = 0;
};

// Throws from the progress event once it reports progress: std::bad_alloc
// (as an observer that runs out of memory) or another exception.
class ThrowOnProgress : public vtkCommand
{
public:
  static ThrowOnProgress* New() { return new ThrowOnProgress; }
  void Execute(vtkObject*, unsigned long, void* callData) override
  {
    const double progress = callData ? *static_cast<double*>(callData) : 0.0;
    if (progress > 0.0 && progress < 1.0)
    {
      ++this->Throws;
      if (this->OutOfMemory)
      {
        throw std::bad_alloc();
      }
      throw std::runtime_error("observer failed");
    }
  }
  bool OutOfMemory = true;
  int Throws = 0;
};

// Changes the filter's second contour value at the first progress event
// (while the first contour is extracted): in place, then grown to many
// values, which reallocates the list's array.
class ChangeValuesOnProgress : public vtkCommand
{
public:
  static ChangeValuesOnProgress* New() { return new ChangeValuesOnProgress; }
  void Execute(vtkObject* caller, unsigned long, void* callData) override
  {
    const double progress = callData ? *static_cast<double*>(callData) : 0.0;
    if (this->Changes == 0 && progress > 0.0 && progress < 0.5)
    {
      ++this->Changes;
      auto* filter = static_cast<vtkPreciseMarchingCubes*>(caller);
      filter->SetValue(1, 120.0);
      for (int i = 2; i < 1000; ++i)
      {
        filter->SetValue(i, 1000.0 + i);
      }
    }
  }
  int Changes = 0;
};

} // anonymous namespace

int main(int, char*[])
{
  vtkNew<vtkRTAnalyticSource> wavelet;
  wavelet->SetWholeExtent(-16, 16, -16, 16, -16, 16);

  vtkNew<vtkPreciseMarchingCubes> pmc;
  pmc->SetInputConnection(wavelet->GetOutputPort());
  pmc->SetValue(0, 160.0);
  vtkNew<pmctest::ErrorObserver> errors;
  pmc->AddObserver(vtkCommand::ErrorEvent, errors);
  pmc->AddObserver(vtkCommand::WarningEvent, errors);

  // Execution counting.
  pmc->Update();
  const vtkIdType triangles = pmc->GetOutput()->GetNumberOfPolys();
  Check(pmc->GetNumberOfExecutions() == 1 && triangles > 0, "first update executes");
  pmc->Update();
  Check(pmc->GetNumberOfExecutions() == 1, "unchanged pipeline does not re-execute");
  pmc->SetEpsilon(pmc->GetEpsilon());
  pmc->Update();
  Check(pmc->GetNumberOfExecutions() == 1, "setting the same epsilon does not re-execute");
  pmc->SetEpsilon(0.002);
  pmc->Update();
  Check(pmc->GetNumberOfExecutions() == 2 &&
      pmc->GetOutput()->GetNumberOfPolys() >= triangles,
    "changing epsilon re-executes (smaller epsilon, at least as many triangles)");
  pmc->SetValue(0, 150.0);
  pmc->Update();
  Check(pmc->GetNumberOfExecutions() == 3, "changing a contour value re-executes");
  pmc->SetMaxLevel(12);
  Check(pmc->GetMaxLevel() == 10, "MaxLevel is clamped to 10");
  pmc->SetRule(7);
  Check(pmc->GetRule() == vtkPreciseMarchingCubes::RULE_B, "Rule is clamped");
  pmc->Update();
  Check(pmc->GetNumberOfExecutions() == 4, "changing MaxLevel and Rule re-executes");
  wavelet->SetMaximum(300.0);
  pmc->Update();
  Check(pmc->GetNumberOfExecutions() == 5, "a modified source re-executes");

  // Statistics.
  Check(pmc->GetNumberOfRefinedTriangles() ==
      static_cast<vtkTypeUInt64>(pmc->GetOutput()->GetNumberOfPolys()) &&
      pmc->GetNumberOfMCTriangles() > 0 &&
      pmc->GetNumberOfMCTriangles() <= pmc->GetNumberOfRefinedTriangles() &&
      pmc->GetMaxLevelReached() <= 10 && pmc->GetMeanLevel() >= 0.0 &&
      pmc->GetMeanLevel() <= pmc->GetMaxLevelReached(),
    "statistics are consistent with the output");

  // MaxTriangles caps the output.
  pmc->SetEpsilon(1e-4);
  pmc->SetMaxTriangles(pmc->GetNumberOfMCTriangles() + 10);
  pmc->Update();
  Check(pmc->GetBudgetReached() &&
      static_cast<vtkTypeUInt64>(pmc->GetOutput()->GetNumberOfPolys()) <=
        pmc->GetNumberOfMCTriangles() + 10,
    "MaxTriangles caps the output and sets BudgetReached");
  pmc->SetMaxTriangles(0);
  pmc->SetEpsilon(0.01);
  pmc->SetMaxLevel(5);
  pmc->SetRuleToA1();

  // Abort from a progress observer.
  vtkNew<AbortOnProgress> abort;
  unsigned long tag = pmc->AddObserver(vtkCommand::ProgressEvent, abort);
  pmc->Modified();
  pmc->Update();
  Check(abort->Calls > 0 && pmc->GetOutput()->GetNumberOfPoints() == 0 &&
      pmc->GetOutput()->GetNumberOfPolys() == 0 && errors->Errors == 0,
    "abort from a ProgressEvent observer gives an empty output without error");
  pmc->RemoveObserver(tag);
  pmc->SetAbortExecute(0);
  pmc->Modified();
  pmc->Update();
  Check(pmc->GetOutput()->GetNumberOfPolys() > 0, "the filter runs again after an abort");

  // A progress observer is called inside the library's extraction (Rust
  // frames, where an exception would abort the process): its exception
  // stops the run there and is reported as an error with an empty output
  // (thrown on through VTK's executive, it would leave the pipeline unable
  // to update again).
  for (const bool outOfMemory : { true, false })
  {
    vtkNew<ThrowOnProgress> thrower;
    thrower->OutOfMemory = outOfMemory;
    tag = pmc->AddObserver(vtkCommand::ProgressEvent, thrower);
    errors->Reset();
    pmc->SetNumberOfThreads(2);
    pmc->Modified();
    bool caught = false;
    try
    {
      pmc->Update();
    }
    catch (...)
    {
      caught = true;
    }
    pmc->RemoveObserver(tag);
    pmc->SetNumberOfThreads(0);
    const char* expected = outOfMemory ? "Out of memory" : "observer failed";
    Check(thrower->Throws == 1 && !caught && errors->Errors == 1 &&
        errors->LastMessage.find(expected) != std::string::npos &&
        pmc->GetOutput()->GetNumberOfPolys() == 0,
      std::string(outOfMemory ? "std::bad_alloc" : "std::runtime_error") +
        " from a progress observer: one throw, an error (" +
        errors->LastMessage.substr(0, 120) + "), empty output");
    pmc->Modified();
    pmc->Update();
    Check(pmc->GetOutput()->GetNumberOfPolys() > 0, "the filter runs again after the exception");
  }

  // Contour values changed by a progress observer during a run: the run
  // contours the values it started with (the list's array may be moved
  // under it), and the next update the new ones.
  {
    pmc->SetNumberOfContours(2);
    pmc->SetValue(0, 150.0);
    pmc->SetValue(1, 170.0);
    pmc->Update();
    const vtkIdType before = pmc->GetOutput()->GetNumberOfPolys();
    vtkNew<ChangeValuesOnProgress> changer;
    tag = pmc->AddObserver(vtkCommand::ProgressEvent, changer);
    errors->Reset();
    pmc->Modified();
    pmc->Update();
    pmc->RemoveObserver(tag);
    const vtkIdType during = pmc->GetOutput()->GetNumberOfPolys();
    Check(changer->Changes == 1 && errors->Errors == 0 && during == before && before > 0,
      "contour values changed during a run: the run keeps its values (" + std::to_string(during) +
        " triangles, " + std::to_string(before) + " before)");
    // (VTK stamps the output after the run, later than the change: as for
    // any filter changed during its run, the next update is asked for.)
    pmc->Modified();
    pmc->Update();
    vtkNew<vtkPreciseMarchingCubes> fresh;
    fresh->SetInputConnection(wavelet->GetOutputPort());
    fresh->SetEpsilon(pmc->GetEpsilon());
    fresh->SetMaxLevel(pmc->GetMaxLevel());
    fresh->SetRule(pmc->GetRule());
    fresh->SetValue(0, 150.0);
    fresh->SetValue(1, 120.0);
    for (int i = 2; i < 1000; ++i)
    {
      fresh->SetValue(i, 1000.0 + i);
    }
    fresh->Update();
    Check(pmc->GetOutput()->GetNumberOfPolys() == fresh->GetOutput()->GetNumberOfPolys() &&
        pmc->GetOutput()->GetNumberOfPolys() != before,
      "the next update contours the changed values");
    pmc->SetNumberOfContours(1);
    pmc->SetValue(0, 150.0);
  }

  // NaN epsilon: the C API rejects it.
  errors->Reset();
  pmc->SetEpsilon(std::numeric_limits<double>::quiet_NaN());
  pmc->Update();
  Check(errors->Errors > 0 && pmc->GetOutput()->GetNumberOfPoints() == 0 &&
      errors->LastMessage.find("psilon") != std::string::npos,
    "NaN epsilon: error (" + errors->LastMessage.substr(0, 160) + ") and empty output");
  pmc->SetEpsilon(0.01);
  errors->Reset();
  pmc->Update();
  Check(errors->Errors == 0 && pmc->GetOutput()->GetNumberOfPolys() > 0,
    "the filter recovers after an error");

  // No scalars.
  {
    vtkNew<vtkImageData> image;
    image->SetDimensions(5, 5, 5);
    vtkNew<vtkPreciseMarchingCubes> f;
    f->SetInputData(image);
    f->SetValue(0, 1.0);
    vtkNew<pmctest::ErrorObserver> obs;
    f->AddObserver(vtkCommand::ErrorEvent, obs);
    f->Update();
    Check(obs->Errors > 0 && f->GetOutput()->GetNumberOfPoints() == 0,
      "no scalars: error (" + obs->LastMessage.substr(0, 120) + ") and empty output");
  }

  // A 2-component array with a bad ArrayComponent.
  {
    const int dims[3] = { 6, 6, 6 };
    auto image = pmctest::RandomVolume(VTK_FLOAT, dims, 0, 1, 3, 2);
    vtkNew<vtkPreciseMarchingCubes> f;
    f->SetInputData(image);
    f->SetValue(0, 0.5);
    f->SetArrayComponent(2);
    vtkNew<pmctest::ErrorObserver> obs;
    f->AddObserver(vtkCommand::ErrorEvent, obs);
    f->Update();
    Check(obs->Errors > 0 && f->GetOutput()->GetNumberOfPoints() == 0,
      "ArrayComponent 2 of 2: error (" + obs->LastMessage.substr(0, 120) + ") and empty output");
    obs->Reset();
    f->SetArrayComponent(1);
    f->Update();
    Check(obs->Errors == 0 && f->GetOutput()->GetNumberOfPolys() > 0, "ArrayComponent 1 of 2 works");
  }

  // A 2D image.
  {
    const int dims[3] = { 6, 6, 1 };
    auto image = pmctest::RandomVolume(VTK_FLOAT, dims, 0, 1, 3);
    vtkNew<vtkPreciseMarchingCubes> f;
    f->SetInputData(image);
    f->SetValue(0, 0.5);
    vtkNew<pmctest::ErrorObserver> obs;
    f->AddObserver(vtkCommand::ErrorEvent, obs);
    f->Update();
    Check(obs->Errors > 0 && f->GetOutput()->GetNumberOfPoints() == 0,
      "2D image: error and empty output");
  }

  // UseSMPTools: the library's tasks on vtkSMPTools give the same output
  // bits as its own threads, on every backend this VTK has; a progress
  // observer can still abort when the calling thread runs tasks (TBB).
  {
    vtkNew<vtkRTAnalyticSource> big;
    big->SetWholeExtent(-40, 40, -40, 40, -40, 40); // many slabs
    auto run = [&](double epsilon, bool smp) {
      vtkNew<vtkPreciseMarchingCubes> f;
      f->SetInputConnection(big->GetOutputPort());
      f->SetValue(0, 180.0);
      f->SetValue(1, 120.0);
      f->SetEpsilon(epsilon);
      f->SetNumberOfThreads(2);
      f->SetUseSMPTools(smp);
      f->Update();
      vtkSmartPointer<vtkPolyData> out = vtkSmartPointer<vtkPolyData>::New();
      out->DeepCopy(f->GetOutput());
      return out;
    };
    auto same = [](vtkPolyData* a, vtkPolyData* b) {
      if (a->GetNumberOfPoints() != b->GetNumberOfPoints() ||
        a->GetNumberOfPolys() != b->GetNumberOfPolys() || a->GetNumberOfPolys() == 0)
      {
        return false;
      }
      vtkDataArray* pa = a->GetPoints()->GetData();
      vtkDataArray* pb = b->GetPoints()->GetData();
      for (vtkIdType i = 0; i < pa->GetNumberOfValues(); ++i)
      {
        if (pa->GetComponent(i / 3, static_cast<int>(i % 3)) !=
          pb->GetComponent(i / 3, static_cast<int>(i % 3)))
        {
          return false;
        }
      }
      vtkDataArray* ca = a->GetPolys()->GetConnectivityArray();
      vtkDataArray* cb = b->GetPolys()->GetConnectivityArray();
      for (vtkIdType i = 0; i < ca->GetNumberOfValues(); ++i)
      {
        if (ca->GetTuple1(i) != cb->GetTuple1(i))
        {
          return false;
        }
      }
      return true;
    };
    const std::string initial = vtkSMPTools::GetBackend();
    for (double epsilon : { 0.0, 0.005 })
    {
      auto own = run(epsilon, false);
      for (const char* backend : { "Sequential", "STDThread", "TBB" })
      {
        if (!vtkSMPTools::SetBackend(backend))
        {
          std::cout << "skip " << backend << " (not built)\n";
          continue;
        }
        vtkSMPTools::Initialize(3);
        Check(same(own, run(epsilon, true)),
          std::string("UseSMPTools on ") + backend + ", epsilon " + std::to_string(epsilon) +
            ": the same output as the library's threads");
      }
    }
    if (vtkSMPTools::SetBackend("TBB"))
    {
      vtkSMPTools::Initialize(2);
      vtkNew<vtkPreciseMarchingCubes> f;
      f->SetInputConnection(big->GetOutputPort());
      f->SetValue(0, 180.0);
      f->SetEpsilon(0.0005);
      f->UseSMPToolsOn();
      vtkNew<AbortOnProgress> stop;
      f->AddObserver(vtkCommand::ProgressEvent, stop);
      f->Update();
      Check(stop->Calls > 0 && f->GetOutput()->GetNumberOfPolys() == 0,
        "UseSMPTools on TBB: a ProgressEvent observer aborts the run");
    }
    vtkSMPTools::SetBackend(initial.c_str());
  }

  // PrintSelf.
  std::ostringstream os;
  pmc->Print(os);
  Check(os.str().find("Epsilon: 0.01") != std::string::npos &&
      os.str().find("Topology: Trilinear") != std::string::npos,
    "PrintSelf prints the properties");

  if (Failures)
  {
    std::cerr << Failures << " check(s) failed\n";
    return EXIT_FAILURE;
  }
  return EXIT_SUCCESS;
}
