// precisemc: the command-line tool. Reads a volume (or generates the
// built-in samples), runs vtkPreciseMarchingCubes, prints a table of each
// run, writes the surface and renders the comparison pictures.
//
// The order of the work is chosen so that a mistake costs nothing: the
// command line, the output paths and every isovalue are checked before
// any extraction, and every file is written through a temporary file.
#include "Common.h"
#include "Display.h"
#include "IO.h"
#include "Measure.h"
#include "Options.h"
#include "Render.h"
#include "Samples.h"

#include "vtkCommand.h"
#include "vtkDataArray.h"
#include "vtkErrorCode.h"
#include "vtkImageData.h"
#include "vtkNew.h"
#include "vtkPointData.h"
#include "vtkPolyData.h"
#include "vtkPreciseMarchingCubes.h"
#include "vtkSMPTools.h"
#include "vtkVersion.h"
#include "vtkXMLImageDataWriter.h"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <limits>
#include <sstream>
#include <thread>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace
{

using pmcapp::Error;
using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start)
{
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// Writes text to stdout at once and throws Error if it could not be
// written (a full disk, a closed descriptor, a reader gone while SIGPIPE
// is ignored: EPIPE), as GNU tools report it: a report lost must not end
// in status 0, nor a run whose report is lost commit its files. With an
// empty text: whether everything written so far got out.
void Print(const std::string& text)
{
  errno = 0;
  std::cout << text << std::flush;
  const int err = errno;
  if (!std::cout || std::ferror(stdout))
  {
    throw Error(std::string("cannot write to standard output: ") +
      std::strerror(err != 0 ? err : EIO));
  }
}

// A standard descriptor the caller closed (">&-") is given /dev/null,
// read-only: no file the tool opens takes its number (the table went into
// whatever file got descriptor 1), and a write to it still fails (EBADF),
// reported by Print().
void ReserveStandardDescriptors()
{
  for (int fd = 0; fd <= 2; ++fd)
  {
    if (fcntl(fd, F_GETFD) == -1 && errno == EBADF)
    {
      const int got = open("/dev/null", O_RDONLY);
      if (got >= 0 && got != fd)
      {
        dup2(got, fd);
        close(got);
      }
    }
  }
}

// A volume to contour, with what the table says about it.
struct DataSet
{
  std::string Name;        // sample name or file name
  std::string Description; // one line
  std::string LoadPhase;   // "generate" or "read"
  double LoadSeconds = 0.0;
  std::vector<double> Values;
  vtkSmartPointer<vtkImageData> Volume;
  // pmcapp::FiniteRange() of the scalars, computed once (a pass over every
  // sample: it was made three times for a file).
  double Range[2] = { 0.0, 0.0 };
  // The default isovalue's line for stdout, printed once every check has
  // passed: a run that fails prints nothing there.
  std::string Announcement;
};

// A progress bar on stderr, drawn only on a terminal and only once the
// extraction has taken more than a second (short runs stay quiet).
class ProgressBar : public vtkCommand
{
public:
  static ProgressBar* New() { return new ProgressBar; }

  void Start(const std::string& label, bool enabled)
  {
    this->Label = label;
    this->Enabled = enabled && isatty(STDERR_FILENO);
    this->Begin = Clock::now();
    this->Drawn = false;
  }

  void Execute(vtkObject*, unsigned long, void* callData) override
  {
    if (!this->Enabled || SecondsSince(this->Begin) < 1.0 || !callData)
    {
      return;
    }
    double fraction = *static_cast<double*>(callData);
    fraction = fraction < 0.0 ? 0.0 : (fraction > 1.0 ? 1.0 : fraction);
    // The filter reports often: redraw only when the percentage moves.
    int percent = static_cast<int>(fraction * 100.0 + 0.5);
    if (this->Drawn && percent == this->Percent)
    {
      return;
    }
    this->Percent = percent;
    const int width = 30;
    int filled = static_cast<int>(fraction * width + 0.5);
    std::fprintf(stderr, "\r%s [%s%s] %3d%%", this->Label.c_str(),
      std::string(filled, '#').c_str(), std::string(width - filled, '.').c_str(), percent);
    std::fflush(stderr);
    this->Drawn = true;
  }

  // Erases the bar so that the table starts on a clean line.
  void Finish()
  {
    if (this->Drawn)
    {
      std::fprintf(stderr, "\r\033[K");
      std::fflush(stderr);
    }
    this->Drawn = false;
  }

private:
  std::string Label;
  bool Enabled = false;
  bool Drawn = false;
  int Percent = -1;
  Clock::time_point Begin;
};

std::string BaseName(const std::string& path)
{
  std::string p = path;
  while (p.size() > 1 && p.back() == '/')
  {
    p.pop_back();
  }
  size_t slash = p.find_last_of('/');
  return slash == std::string::npos ? p : p.substr(slash + 1);
}

std::string ValuesText(const std::vector<double>& values)
{
  std::string text;
  for (double v : values)
  {
    text += (text.empty() ? "" : ", ") + pmcapp::General(v);
  }
  return text;
}

// The samples to generate: none for an input file.
std::vector<std::string> SampleList(const pmcapp::Options& o)
{
  if (!o.Input.empty())
  {
    return {};
  }
  if (o.Sample.empty() || o.Sample == "all")
  {
    return pmcapp::SampleNames();
  }
  return { o.Sample };
}

std::vector<DataSet> LoadDataSets(const pmcapp::Options& o)
{
  std::vector<DataSet> sets;
  if (!o.Input.empty())
  {
    DataSet d;
    Clock::time_point start = Clock::now();
    std::vector<std::string> warnings;
    d.Volume = pmcapp::ReadVolume(o.Input, o.Array, warnings, d.Range);
    for (const std::string& w : o.Quiet ? std::vector<std::string>() : warnings)
    {
      std::cerr << "precisemc: warning: '" << o.Input << "': " << w << "\n";
    }
    d.LoadSeconds = SecondsSince(start);
    d.LoadPhase = "read";
    d.Name = BaseName(o.Input);
    d.Description = pmcapp::DescribeVolume(d.Volume);
    const double* range = d.Range;
    if (o.Values.empty())
    {
      if (range[0] == range[1])
      {
        throw Error("the scalars of " + d.Name + " are all " + pmcapp::General(range[0]) +
          " (the finite ones): no isovalue gives a surface");
      }
      // Halved first where the sum overflows (values near DBL_MAX); not
      // always, which would round the middle of subnormal ranges to 0.
      const double sum = range[0] + range[1];
      const double middle = std::isfinite(sum) ? 0.5 * sum : 0.5 * range[0] + 0.5 * range[1];
      // Two adjacent doubles (1 and 1 + 2^-52, 0 and the least subnormal)
      // have no number between them: the middle rounds to the minimum,
      // which no cell crosses (refused below). The maximum is crossed
      // wherever the two values meet in a cell.
      const bool between = middle > range[0];
      d.Values.push_back(between ? middle : range[1]);
      d.Announcement = "isovalue " + pmcapp::General(d.Values[0]) + ": the " +
        (between ? "middle" : "maximum") + " of the scalar range [" +
        pmcapp::General(range[0]) + ", " + pmcapp::General(range[1]) + "] of " + d.Name +
        (between ? "" : " (no number lies between its ends)") + " (set it with -v)";
    }
    sets.push_back(d);
  }
  else
  {
    for (const auto& name : SampleList(o))
    {
      DataSet d;
      Clock::time_point start = Clock::now();
      pmcapp::Sample s = pmcapp::MakeSample(name);
      d.LoadSeconds = SecondsSince(start);
      d.LoadPhase = "generate";
      d.Name = s.Name;
      d.Description = s.Description;
      d.Volume = s.Volume;
      pmcapp::FiniteRange(d.Volume->GetPointData()->GetScalars(), d.Range);
      if (o.Values.empty())
      {
        d.Values.push_back(s.IsoValue);
      }
      sets.push_back(d);
    }
  }

  // Every isovalue must cut the data: outside the range the surface is
  // empty, which is almost certainly a mistake.
  for (auto& d : sets)
  {
    if (!o.Values.empty())
    {
      d.Values = o.Values;
    }
    const double* range = d.Range;
    // Which array, when the file has several (--array chooses).
    vtkDataArray* scalars = d.Volume->GetPointData()->GetScalars();
    const std::string which =
      d.Volume->GetPointData()->GetNumberOfArrays() > 1 && scalars->GetName()
      ? std::string(" (array '") + scalars->GetName() + "')"
      : std::string();
    for (double v : d.Values)
    {
      if (v < range[0] || v > range[1])
      {
        throw Error("isovalue " + pmcapp::General(v) + " is outside the scalar range [" +
          pmcapp::General(range[0]) + ", " + pmcapp::General(range[1]) + "] of " + d.Name +
          which);
      }
      if (v == range[0])
      {
        // A sample at the isovalue counts as above it (as in
        // vtkMarchingCubes): at the minimum no cell is crossed.
        throw Error("isovalue " + pmcapp::General(v) + " is the minimum of the scalar range [" +
          pmcapp::General(range[0]) + ", " + pmcapp::General(range[1]) + "] of " + d.Name +
          which + ": every sample is at or above it, so there is no surface");
      }
    }
  }
  return sets;
}

// Whether single-precision points would round the surface by more than a
// tenth of epsilon (1/100 of a cell with refinement off): float keeps 24
// bits, so far from the origin (geographic coordinates, an extent that
// starts at 2^31) its rounding exceeds what refinement achieved, or the
// coordinates overflow it.
bool NeedsDoublePoints(vtkImageData* volume, double epsilon)
{
  double bounds[6];
  volume->GetBounds(bounds);
  double largest = 0.0;
  for (double b : bounds)
  {
    largest = std::max(largest, std::fabs(b));
  }
  const double* spacing = volume->GetSpacing();
  double cell = std::min({ std::fabs(spacing[0]), std::fabs(spacing[1]), std::fabs(spacing[2]) });
  const double tolerance = epsilon > 0.0 ? 0.1 * epsilon : 0.01;
  return !std::isfinite(largest) || largest > std::numeric_limits<float>::max() ||
    largest * std::ldexp(1.0, -24) > tolerance * cell;
}

void Configure(vtkPreciseMarchingCubes* f, const pmcapp::Options& o, bool levels)
{
  vtkImageData* volume = vtkImageData::SafeDownCast(f->GetInputDataObject(0, 0));
  // DEFAULT rather than SINGLE: float unless the filter's own rule finds
  // it cannot tell the cells' points apart (then double, not a warning).
  f->SetOutputPointsPrecision(volume && NeedsDoublePoints(volume, o.Epsilon)
      ? vtkAlgorithm::DOUBLE_PRECISION
      : vtkAlgorithm::DEFAULT_PRECISION);
  f->SetEpsilon(o.Epsilon);
  f->SetMaxLevel(o.MaxLevel);
  f->SetRule(o.Rule);
  f->SetTopology(o.Topology);
  f->SetReconstructionFilter(o.Filter);
  f->SetComputeNormals(o.Normals != 0);
  if (o.Normals != 0)
  {
    f->SetNormalMode(o.Normals);
  }
  // Only a written surface holds the gradients (see main()).
  f->SetComputeGradients(o.Gradients && !o.Output.empty());
  f->SetMaxTriangles(static_cast<vtkTypeUInt64>(o.MaxTriangles));
  f->SetNumberOfThreads(o.Threads);
  f->SetUseSMPTools(o.SMP);
  f->ComputeScalarsOn();
  f->SetComputeLevels(levels);
}

// vtkMarchingCubes's surface of the values (pmcapp::RunMarchingCubes),
// its errors naming the volume.
vtkSmartPointer<vtkPolyData> Baseline(
  const DataSet& d, const std::vector<double>& values, unsigned long long* dropped = nullptr)
{
  try
  {
    return pmcapp::RunMarchingCubes(d.Volume, values, dropped);
  }
  catch (const Error& e)
  {
    throw Error(d.Name + ": " + e.what(), e.Status);
  }
}

// PreciseMC's surface of one isovalue alone, for --measure. The surfaces of
// several isovalues cannot be told apart in the filter's output: its point
// scalars are in the input's type (on uint8 data 50.5 is stored as 50).
vtkSmartPointer<vtkPolyData> ExtractOne(const DataSet& d, double value, const pmcapp::Options& o)
{
  vtkNew<vtkPreciseMarchingCubes> filter;
  filter->SetInputData(d.Volume);
  filter->SetValue(0, value);
  Configure(filter, o, false);
  filter->SetComputeNormals(false);
  filter->SetComputeGradients(false);
  pmcapp::TakeVTKErrors();
  filter->Update();
  std::vector<std::string> errors = pmcapp::TakeVTKErrors();
  if (!errors.empty())
  {
    throw Error(d.Name + ": " + errors.front());
  }
  pmcapp::TakeVTKWarnings();
  auto out = vtkSmartPointer<vtkPolyData>::New();
  out->ShallowCopy(filter->GetOutput());
  return out;
}

std::string Row(const std::string& key, const std::string& value)
{
  std::string padded = "  " + key;
  padded.resize(22, ' ');
  return padded + value + "\n";
}

std::string Seconds(double s)
{
  return pmcapp::Fixed(s, s < 10.0 ? 3 : 1) + " s";
}

}

int main(int argc, char* argv[])
{
  ReserveStandardDescriptors();
  // Past a file size limit (ulimit -f) a write raises SIGXFSZ, whose
  // default action killed the tool half-way through a file, its temporary
  // left behind. Ignored, the write fails with EFBIG instead, reported as
  // a full disk is (the old file kept, the temporaries removed).
  std::signal(SIGXFSZ, SIG_IGN);
  pmcapp::CaptureVTKMessages();
  try
  {
    pmcapp::Options o = pmcapp::ParseArguments(argc, argv);
    if (o.Help)
    {
      Print(pmcapp::UsageText());
      return 0;
    }
    if (o.Version)
    {
      Print(std::string("precisemc ") + PRECISEMC_APP_VERSION + " (VTK " +
        vtkVersion::GetVTKVersion() + ")\n");
      return 0;
    }
    if (o.SMP && o.Threads > 0)
    {
      // TBB warns on stderr (which -q keeps for errors) when asked for
      // more threads than the machine has: ask for at most that many.
      int threads = o.Threads;
      unsigned cores = std::thread::hardware_concurrency();
      if (cores > 0 && static_cast<unsigned>(threads) > cores)
      {
        threads = static_cast<int>(cores);
      }
      vtkSMPTools::Initialize(threads);
    }

    // Outputs first: a bad path should not cost an extraction. With
    // several volumes the paths written are the per-volume ones (o.Output
    // itself is never written then), so those are the ones checked.
    const std::vector<std::string> samples = SampleList(o);
    const bool several = samples.size() > 1;
    auto pathFor = [several](const std::string& path, const std::string& name) {
      return several ? pmcapp::WithSuffix(path, name) : path;
    };
    const std::vector<std::string> names = several ? samples : std::vector<std::string>{ "" };
    if (o.Gradients && o.Output.empty() && !o.Quiet)
    {
      // The array would be computed and dropped (the table does not
      // show it): said, and not computed.
      std::cerr << "precisemc: warning: --gradients without -o: no surface is written, so "
                   "no gradients are computed"
                << std::endl;
    }
    if (!o.Output.empty())
    {
      pmcapp::CheckSurfaceFormat(o.Output);
      for (const auto& name : names)
      {
        pmcapp::CheckWritable(pathFor(o.Output, name), "surface");
      }
    }
    if (!o.WriteVolume.empty())
    {
      for (const auto& name : names)
      {
        pmcapp::CheckWritable(pathFor(o.WriteVolume, name), "volume");
      }
    }
    if (!o.Compare.empty())
    {
      pmcapp::CheckWritable(o.Compare, "picture");
    }
    if (!o.Distance.empty())
    {
      pmcapp::CheckWritable(o.Distance, "picture");
    }
    // Two spellings of one file ("a.png", "./a.png", a link to the
    // directory) would share a temporary, and one output would overwrite
    // the other.
    {
      std::vector<std::pair<std::string, std::string>> written;
      for (const auto& name : names)
      {
        if (!o.Output.empty())
        {
          written.emplace_back(pathFor(o.Output, name), "");
        }
        if (!o.WriteVolume.empty())
        {
          written.emplace_back(pathFor(o.WriteVolume, name), "");
        }
      }
      for (const std::string* png : { &o.Compare, &o.Distance })
      {
        if (!png->empty())
        {
          written.emplace_back(*png, "");
        }
      }
      for (auto& w : written)
      {
        w.second = pmcapp::CanonicalPath(w.first);
      }
      // Nor may an output be the input file (or a link to it): a failed
      // run would keep it, a run that works would replace it.
      struct stat in;
      if (!o.Input.empty() && stat(o.Input.c_str(), &in) == 0 && S_ISREG(in.st_mode))
      {
        for (const auto& w : written)
        {
          struct stat out;
          if (stat(w.first.c_str(), &out) == 0 && out.st_dev == in.st_dev &&
            out.st_ino == in.st_ino)
          {
            throw Error("'" + w.first + "' names the input file '" + o.Input + "'", 2);
          }
        }
      }
      for (size_t a = 0; a < written.size(); ++a)
      {
        for (size_t b = a + 1; b < written.size(); ++b)
        {
          if (written[a].second == written[b].second)
          {
            throw Error("'" + written[a].first + "' and '" + written[b].first +
                "' name the same file",
              2);
          }
        }
      }
    }
    const bool pictures = !o.Compare.empty() || !o.Distance.empty();
    if (pictures)
    {
      pmcapp::EnsureDisplay();
    }

    std::vector<DataSet> sets = LoadDataSets(o);
    for (const auto& d : sets)
    {
      if (!o.Quiet && !d.Announcement.empty())
      {
        Print(d.Announcement + "\n");
      }
    }
    // Every file of the run is committed at its end, after the pictures.
    pmcapp::PendingFiles files;

    std::string refinedLabel = o.Epsilon > 0.0 && o.MaxLevel > 0
      ? "PreciseMC (eps " + pmcapp::General(o.Epsilon) + ", level <= " +
        std::to_string(o.MaxLevel) + ")"
      : "PreciseMC (no refinement)";
    std::vector<pmcapp::Panel> panels;
    vtkNew<ProgressBar> progress;

    for (auto& d : sets)
    {
      std::string output = o.Output.empty() ? std::string() : pathFor(o.Output, d.Name);

      vtkNew<vtkPreciseMarchingCubes> filter;
      filter->SetInputData(d.Volume);
      for (size_t i = 0; i < d.Values.size(); ++i)
      {
        filter->SetValue(static_cast<int>(i), d.Values[i]);
      }
      // The refinement level of each triangle is kept where the format can
      // hold a cell array.
      Configure(filter, o, pmcapp::Extension(output) == ".vtp");
      filter->AddObserver(vtkCommand::ProgressEvent, progress);
      progress->Start(d.Name, !o.Quiet);

      Clock::time_point start = Clock::now();
      pmcapp::TakeVTKErrors();
      filter->Update();
      double extractSeconds = SecondsSince(start);
      progress->Finish();
      std::vector<std::string> errors = pmcapp::TakeVTKErrors();
      if (!errors.empty())
      {
        throw Error(d.Name + ": " + errors.front());
      }
      pmcapp::TakeVTKWarnings();
      if (filter->GetOutput()->GetNumberOfPolys() == 0)
      {
        // Every isovalue is inside the scalar range (checked before the
        // work), yet the surface is empty: the cells with NaN or infinite
        // samples are skipped (a low sample whose neighbours are all NaN),
        // or, with no cell skipped, the cells crossed meet the isovalue
        // only at samples equal to it, where the surface shrinks to a
        // point or to flat pieces that cancel (a peak or a ridge of
        // samples at the isovalue, as at the data's maximum: this said
        // "no cell with only finite samples is crossed" of finite data).
        // The empty file written is most likely not what was wanted: said
        // even with -q, the status left 0.
        const bool plural = d.Values.size() > 1;
        std::cerr << "precisemc: warning: " << d.Name << ": the surface is empty: ";
        if (filter->GetNumberOfSkippedCells() > 0)
        {
          std::cerr << "no cell with only finite samples is crossed at isovalue"
                    << (plural ? "s " : " ") << ValuesText(d.Values);
        }
        else
        {
          std::cerr << "the cells crossed at isovalue" << (plural ? "s " : " ")
                    << ValuesText(d.Values)
                    << " meet it only at samples equal to it (a peak or a ridge at the "
                    << (plural ? "isovalues" : "isovalue")
                    << ", as at the data's maximum), which give no triangles";
        }
        std::cerr << (output.empty() ? "" : " (the file written holds no triangles)") << std::endl;
      }

      pmcapp::Panel panel;
      panel.Name = d.Name;
      panel.Volume = d.Volume;
      panel.Refined = vtkSmartPointer<vtkPolyData>::New();
      panel.Refined->ShallowCopy(filter->GetOutput());
      panel.RefinedLabel = refinedLabel;

      double mcSeconds = 0.0, distanceSeconds = 0.0, writeSeconds = 0.0, measureSeconds = 0.0;
      if (pictures || o.Measure)
      {
        start = Clock::now();
        panel.MC = Baseline(d, d.Values, &panel.MCDropped);
        mcSeconds = SecondsSince(start);
      }
      // --measure: one isovalue at a time; with several, both surfaces are
      // extracted again for each value alone.
      std::vector<pmcapp::Distance> mcDistances, refinedDistances;
      if (o.Measure)
      {
        start = Clock::now();
        const unsigned density = static_cast<unsigned>(o.MeasureDensity < 0 ? 3 : o.MeasureDensity);
        // --threads bounds the measure too (it used all cores).
        const unsigned measureThreads = static_cast<unsigned>(o.Threads);
        for (double v : d.Values)
        {
          const bool alone = d.Values.size() == 1;
          vtkSmartPointer<vtkPolyData> mcSurface =
            alone ? panel.MC : Baseline(d, std::vector<double>{ v });
          vtkSmartPointer<vtkPolyData> refinedSurface =
            alone ? panel.Refined : ExtractOne(d, v, o);
          mcDistances.push_back(
            pmcapp::MeasureDistance(d.Volume, v, mcSurface, density, measureThreads));
          refinedDistances.push_back(
            pmcapp::MeasureDistance(d.Volume, v, refinedSurface, density, measureThreads));
        }
        measureSeconds = SecondsSince(start);
      }
      if (!o.Distance.empty())
      {
        start = Clock::now();
        pmcapp::ComputeDistance(panel);
        distanceSeconds = SecondsSince(start);
      }
      if (!o.WriteVolume.empty())
      {
        std::string path = pathFor(o.WriteVolume, d.Name);
        std::string tmp = files.Add(path);
        vtkNew<vtkXMLImageDataWriter> writer;
        writer->SetFileName(tmp.c_str());
        writer->SetInputData(d.Volume);
        writer->SetDataModeToAppended();
        writer->EncodeAppendedDataOff();
        // Write() returns 1 even when the disk filled up: the error code
        // and the captured errors tell.
        pmcapp::TakeVTKErrors();
        int ok = writer->Write();
        std::string why = pmcapp::BestError(pmcapp::TakeVTKErrors());
        if (!ok || writer->GetErrorCode() != 0 || !why.empty())
        {
          pmcapp::RemoveFile(tmp);
          if (why.empty())
          {
            why = writer->GetErrorCode() != 0
              ? vtkErrorCode::GetStringFromErrorCode(writer->GetErrorCode())
              : "the writer failed";
          }
          throw Error("cannot write the volume '" + path + "': " + pmcapp::ForUser(why, tmp, path));
        }
      }
      if (!output.empty())
      {
        start = Clock::now();
        pmcapp::WriteSurface(panel.Refined, output, files.Add(output), o.Quiet);
        writeSeconds = SecondsSince(start);
      }

      if (!o.Quiet)
      {
        int dims[3];
        d.Volume->GetDimensions(dims);
        unsigned long long cells = static_cast<unsigned long long>(dims[0] - 1) *
          static_cast<unsigned long long>(dims[1] - 1) * static_cast<unsigned long long>(dims[2] - 1);
        unsigned long long mc = filter->GetNumberOfMCTriangles();
        unsigned long long refined = filter->GetNumberOfRefinedTriangles();

        std::ostringstream table;
        table << d.Name << ": " << d.Description << "\n";
        table << Row(d.Values.size() > 1 ? "isovalues" : "isovalue", ValuesText(d.Values));
        if (o.Filter != 0)
        {
          table << Row("filter", pmcapp::FilterName(o.Filter) + " (refinement follows it)");
        }
        std::string cellText = pmcapp::Grouped(cells) + " (" +
          pmcapp::Grouped(filter->GetNumberOfAmbiguousCells()) + " ambiguous";
        if (filter->GetNumberOfSkippedCells() > 0)
        {
          cellText += ", " + pmcapp::Grouped(filter->GetNumberOfSkippedCells()) + " non-finite";
        }
        if (d.Values.size() > 1)
        {
          // The filter counts each isovalue's cells: with repeated or
          // several values a cell counts once per value.
          cellText += "; summed over the " + std::to_string(d.Values.size()) + " isovalues";
        }
        table << Row("cells", cellText + ")");
        table << Row("MC triangles", pmcapp::Grouped(mc));
        std::string outText = pmcapp::Grouped(refined);
        if (mc > 0)
        {
          outText += " (x" + pmcapp::Fixed(static_cast<double>(refined) / mc, 2) + ")";
        }
        if (filter->GetBudgetReached())
        {
          outText += ", capped by --max-triangles";
        }
        table << Row("output triangles", outText);
        table << Row("maxL / meanL",
          std::to_string(filter->GetMaxLevelReached()) + " / " +
            pmcapp::Fixed(filter->GetMeanLevel(), 2));
        if (filter->GetNumberOfFacesAboveEpsilon() > 0)
        {
          table << Row("above epsilon",
            pmcapp::Grouped(filter->GetNumberOfFacesAboveEpsilon()) +
              " triangles at the level cap");
        }
        if (panel.MCDropped > 0)
        {
          table << Row("MC non-finite", pmcapp::Grouped(panel.MCDropped) +
              " vtkMarchingCubes triangles in cells with NaN or infinite samples, or with points "
              "its single precision cannot hold, dropped (not shown, not measured)");
        }
        if (!o.Distance.empty() && panel.MC->GetNumberOfPolys() == 0)
        {
          table << Row("MC to refined", "no vtkMarchingCubes triangles to measure");
        }
        else if (!o.Distance.empty())
        {
          table << Row("MC to refined", "max " + pmcapp::Fixed(panel.MaxDistance, 3) + ", mean " +
              pmcapp::Fixed(panel.MeanDistance, 3) + " cells" +
              (panel.Unmeasured > 0
                  ? " (" + pmcapp::Grouped(static_cast<unsigned long long>(panel.Unmeasured)) +
                    " points with no finite distance left out)"
                  : std::string()));
        }
        for (size_t i = 0; i < mcDistances.size(); ++i)
        {
          std::string which = d.Values.size() > 1 ? " (v " + pmcapp::General(d.Values[i]) + ")" : "";
          auto text = [](const pmcapp::Distance& m, const std::string& who) {
            // An empty surface has no distance: say so rather than print
            // zeros that read like a perfect result.
            if (m.Triangles == 0)
            {
              return "no triangles to measure (" + who + ")";
            }
            if (m.Samples == 0)
            {
              // Every point unresolved: the data have no finite cells on
              // the isovalue.
              return "no isosurface to measure against (" + who + ", " +
                pmcapp::Grouped(m.Unresolved) + " points unresolved)";
            }
            std::string t = "max " + pmcapp::Fixed(m.Max, 5) + ", mean " +
              pmcapp::Fixed(m.Mean, 5) + " cells (" + who + ", " + pmcapp::Grouped(m.Samples) +
              " points";
            if (m.Unresolved > 0)
            {
              t += ", " + pmcapp::Grouped(m.Unresolved) + " unresolved";
            }
            return t + ")";
          };
          table << Row("S_K distance MC", text(mcDistances[i], "vtkMarchingCubes" + which));
          table << Row("S_K distance out", text(refinedDistances[i], "PreciseMC" + which));
        }
        std::string times = d.LoadPhase + " " + Seconds(d.LoadSeconds) + " | extract " +
          Seconds(extractSeconds);
        if (pictures || o.Measure)
        {
          times += " | vtkMarchingCubes " + Seconds(mcSeconds);
        }
        if (o.Measure)
        {
          times += " | measure " + Seconds(measureSeconds);
        }
        if (!o.Distance.empty())
        {
          times += " | distance " + Seconds(distanceSeconds);
        }
        if (!output.empty())
        {
          times += " | write " + Seconds(writeSeconds);
        }
        table << Row("time", times);
        if (!output.empty())
        {
          // The destination: the file is renamed there once the whole run
          // has succeeded (a later failure leaves nothing behind).
          table << Row("output file", output);
        }
        Print(table.str());
      }
      panels.push_back(panel);
    }

    std::string pictureLines;
    if (!o.Compare.empty())
    {
      Clock::time_point start = Clock::now();
      pmcapp::RenderCompare(panels, o.Compare, files.Add(o.Compare));
      pictureLines +=
        "compare picture: " + o.Compare + " (" + Seconds(SecondsSince(start)) + ")\n";
    }
    if (!o.Distance.empty())
    {
      Clock::time_point start = Clock::now();
      pmcapp::RenderDistance(panels, o.Distance, files.Add(o.Distance));
      pictureLines +=
        "distance picture: " + o.Distance + " (" + Seconds(SecondsSince(start)) + ")\n";
    }
    // Everything is printed, and got out whole (Print checks), before the
    // commit: a reader of stdout that quits early (SIGPIPE), or a full
    // disk under a redirected report, fails the run before any file is
    // in place. Nothing is written after it.
    if (!o.Quiet)
    {
      Print(pictureLines);
    }
    Print("");
    files.Commit();
    return 0;
  }
  catch (const Error& e)
  {
    std::cerr << "precisemc: error: " << e.what() << std::endl;
    return e.Status;
  }
  catch (const std::bad_alloc&)
  {
    std::cerr << "precisemc: error: out of memory" << std::endl;
    return 1;
  }
  catch (const std::exception& e)
  {
    std::cerr << "precisemc: error: " << e.what() << std::endl;
    return 1;
  }
}
