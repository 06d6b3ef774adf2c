// Command-line parsing of the precisemc tool. Every mistake becomes one
// pmcapp::Error line with exit status 2 (usage error), before any work.
#include "Options.h"

#include "Common.h"
#include "Samples.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <set>

namespace pmcapp
{
namespace
{

const char* const RuleNames[] = { "A", "A1", "A2", "B" };
const char* const TopologyNames[] = { "trilinear", "classic" };
// In the order of vtkPreciseMarchingCubes::ReconstructionFilters.
const char* const FilterNames[] = { "trilinear", "catmull-rom", "bspline",
  "bspline-interpolating" };
const char* const NormalsNames[] = { "none", "gradient", "central" };

std::string Lower(std::string text)
{
  std::transform(text.begin(), text.end(), text.begin(),
    [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

[[noreturn]] void Usage(const std::string& message)
{
  throw Error(message + " (see precisemc --help)", 2);
}

double ParseDouble(const std::string& option, const std::string& text)
{
  // strtod skips leading blanks and reads hexadecimal ("0x10" is 16): a
  // number is written in decimal and nothing else, as ParseCount wants
  // its digits (" 0.1" was accepted where "0.1 " was refused).
  const size_t digits = text.find_first_not_of("+-");
  if (!text.empty() && std::isspace(static_cast<unsigned char>(text[0])))
  {
    Usage(option + ": '" + text + "' is not a finite number");
  }
  if (digits != std::string::npos && text.size() > digits + 1 && text[digits] == '0' &&
    (text[digits + 1] == 'x' || text[digits + 1] == 'X'))
  {
    Usage(option + ": '" + text + "' is not a decimal number");
  }
  const char* begin = text.c_str();
  char* end = nullptr;
  errno = 0;
  double value = std::strtod(begin, &end);
  // ERANGE flags overflow (read as +-HUGE_VAL) and underflow: 1e-310 is
  // read as a subnormal, a usable value, but below the least subnormal
  // (about 4.9e-324) the number becomes 0, which for --epsilon means no
  // refinement at all: the opposite of what a tiny epsilon asks for.
  const bool overflow = errno == ERANGE && std::fabs(value) >= HUGE_VAL;
  if (text.empty() || end != begin + text.size() || overflow || !std::isfinite(value))
  {
    Usage(option + ": '" + text + "' is not a finite number");
  }
  if (errno == ERANGE && value == 0.0)
  {
    Usage(option + ": '" + text + "' underflows to 0");
  }
  return value;
}

// A non-negative integer no larger than max.
unsigned long long ParseCount(
  const std::string& option, const std::string& text, unsigned long long max)
{
  bool digits = !text.empty() &&
    std::all_of(text.begin(), text.end(), [](unsigned char c) { return std::isdigit(c) != 0; });
  if (!digits)
  {
    Usage(option + ": '" + text + "' is not a non-negative integer");
  }
  errno = 0;
  unsigned long long value = std::strtoull(text.c_str(), nullptr, 10);
  if (errno == ERANGE || value > max)
  {
    Usage(option + ": " + text + " is too large (at most " + std::to_string(max) + ")");
  }
  return value;
}

int ParseName(const std::string& option, const std::string& text, const char* const* names,
  int count, bool caseSensitive = false)
{
  std::string wanted = caseSensitive ? text : Lower(text);
  std::string known;
  for (int i = 0; i < count; ++i)
  {
    std::string name = caseSensitive ? names[i] : Lower(names[i]);
    if (wanted == name)
    {
      return i;
    }
    known += (i ? "|" : "") + std::string(names[i]);
  }
  Usage(option + ": unknown value '" + text + "' (expected " + known + ")");
}

}

std::string RuleName(int rule)
{
  return rule >= 0 && rule < 4 ? RuleNames[rule] : "?";
}

std::string TopologyName(int topology)
{
  return topology >= 0 && topology < 2 ? TopologyNames[topology] : "?";
}

std::string FilterName(int filter)
{
  return filter >= 0 && filter < 4 ? FilterNames[filter] : "?";
}

std::string NormalsName(int normals)
{
  return normals >= 0 && normals < 3 ? NormalsNames[normals] : "?";
}

Options ParseArguments(int argc, char* argv[])
{
  Options o;
  bool optionsEnded = false;
  std::set<std::string> given; // the options seen, by their long names
  for (int i = 1; i < argc; ++i)
  {
    std::string arg = argv[i];
    if (optionsEnded || arg.empty() || arg[0] != '-' || arg == "-")
    {
      if (!o.Input.empty())
      {
        Usage("only one input is accepted, got '" + o.Input + "' and '" + arg + "'");
      }
      o.Input = arg;
      if (o.Input.empty())
      {
        Usage("the input file name is empty");
      }
      continue;
    }
    if (arg == "--")
    {
      optionsEnded = true;
      continue;
    }

    // --name=value, --name value, -x value or -xvalue.
    std::string name = arg;
    std::string inlineValue;
    bool hasInline = false;
    if (arg.compare(0, 2, "--") == 0)
    {
      size_t eq = arg.find('=');
      if (eq != std::string::npos)
      {
        name = arg.substr(0, eq);
        inlineValue = arg.substr(eq + 1);
        hasInline = true;
      }
    }
    else if (arg.size() > 2)
    {
      name = arg.substr(0, 2);
      inlineValue = arg.substr(2);
      hasInline = true;
    }
    auto value = [&]() -> std::string {
      if (hasInline)
      {
        hasInline = false;
        return inlineValue;
      }
      if (i + 1 >= argc)
      {
        Usage(name + " needs a value");
      }
      return argv[++i];
    };
    auto flag = [&]() {
      if (hasInline)
      {
        Usage(name + " takes no value");
      }
    };

    // An option given twice is a mistake: the second silently replaced the
    // first (-o a -o b wrote b only, --epsilon 0.1 --epsilon 0 ran plain
    // Marching Cubes). Only -v adds up (isovalues are appended).
    static const std::pair<const char*, const char*> shortNames[] = { { "-h", "--help" },
      { "-q", "--quiet" }, { "-v", "--value" }, { "-o", "--output" } };
    std::string option = name;
    std::string shown = name;
    for (const auto& alias : shortNames)
    {
      if (name == alias.first || name == alias.second)
      {
        option = alias.second;
        shown = std::string(alias.first) + "/" + alias.second;
      }
    }
    if (option != "--value" && !given.insert(option).second)
    {
      Usage(shown + " is given twice (only -v/--value can be repeated)");
    }

    if (name == "-h" || name == "--help")
    {
      flag();
      o.Help = true;
    }
    else if (name == "--version")
    {
      flag();
      o.Version = true;
    }
    else if (name == "--smp")
    {
      flag();
      o.SMP = true;
    }
    else if (name == "--gradients")
    {
      flag();
      o.Gradients = true;
    }
    else if (name == "-q" || name == "--quiet")
    {
      flag();
      o.Quiet = true;
    }
    else if (name == "--array")
    {
      o.Array = value();
      if (o.Array.empty())
      {
        Usage("--array needs a non-empty array name");
      }
    }
    else if (name == "-v" || name == "--value")
    {
      o.Values.push_back(ParseDouble(name, value()));
    }
    else if (name == "--epsilon")
    {
      o.Epsilon = ParseDouble(name, value());
      if (o.Epsilon < 0.0)
      {
        Usage("--epsilon must be >= 0 (got " + General(o.Epsilon) + ")");
      }
    }
    else if (name == "--max-level")
    {
      o.MaxLevel = static_cast<int>(ParseCount(name, value(), 10));
    }
    else if (name == "--rule")
    {
      o.Rule = ParseName(name, value(), RuleNames, 4);
    }
    else if (name == "--topology")
    {
      o.Topology = ParseName(name, value(), TopologyNames, 2);
    }
    else if (name == "--filter")
    {
      o.Filter = ParseName(name, value(), FilterNames, 4);
    }
    else if (name == "--normals")
    {
      o.Normals = ParseName(name, value(), NormalsNames, 3);
    }
    else if (name == "--max-triangles")
    {
      o.MaxTriangles = ParseCount(name, value(), std::numeric_limits<unsigned long long>::max());
    }
    else if (name == "--threads")
    {
      o.Threads = static_cast<int>(ParseCount(name, value(), 4096));
    }
    else if (name == "-o" || name == "--output")
    {
      o.Output = value();
      if (o.Output.empty())
      {
        Usage(name + ": the file name is empty");
      }
    }
    else if (name == "--compare" || name == "--distance")
    {
      std::string& picture = name == "--compare" ? o.Compare : o.Distance;
      picture = value();
      if (picture.empty())
      {
        Usage(name + ": the file name is empty");
      }
    }
    else if (name == "--write-volume")
    {
      o.WriteVolume = value();
      if (OnlyExtension(o.WriteVolume) == ".vti")
      {
        Usage("--write-volume: '" + o.WriteVolume + "' has no base name, only the extension .vti");
      }
      if (Extension(o.WriteVolume) != ".vti")
      {
        Usage("--write-volume writes VTK XML image data: '" + o.WriteVolume +
          "' does not end in .vti");
      }
    }
    else if (name == "--measure")
    {
      flag();
      o.Measure = true;
    }
    else if (name == "--measure-density")
    {
      o.MeasureDensity = static_cast<int>(ParseCount(name, value(), 64));
      if (o.MeasureDensity < 1)
      {
        Usage("--measure-density must be between 1 and 64 (got 0)");
      }
    }
    else if (name == "--sample")
    {
      std::string sample = Lower(value());
      std::vector<std::string> names = SampleNames();
      if (sample != "all" && std::find(names.begin(), names.end(), sample) == names.end())
      {
        std::string known;
        for (const auto& n : names)
        {
          known += n + "|";
        }
        Usage("--sample: unknown sample '" + sample + "' (expected " + known + "all)");
      }
      o.Sample = sample;
    }
    else
    {
      Usage("unknown option '" + name + "'");
    }
  }

  if (!o.Input.empty() && !o.Sample.empty())
  {
    Usage("give either an input file or --sample, not both");
  }
  for (const std::string* png : { &o.Compare, &o.Distance })
  {
    if (!png->empty() && OnlyExtension(*png) == ".png")
    {
      Usage("'" + *png + "' has no base name, only the extension .png");
    }
    if (!png->empty() && Extension(*png) != ".png")
    {
      Usage("pictures are written as PNG: '" + *png + "' does not end in .png");
    }
  }
  for (size_t i = 0; i < o.Values.size(); ++i)
  {
    for (size_t j = 0; j < i; ++j)
    {
      if (o.Values[i] == o.Values[j])
      {
        // Its surface would be written twice, coincident.
        Usage("isovalue " + General(o.Values[i]) + " is given twice");
      }
    }
  }
  if (!o.Array.empty() && o.Input.empty())
  {
    Usage("--array chooses a point array of an input file; the samples have one");
  }
  if (o.MeasureDensity >= 0 && !o.Measure)
  {
    Usage("--measure-density needs --measure");
  }
  if (o.Measure && o.Quiet)
  {
    Usage("--measure prints its distances in the table, which --quiet turns off");
  }
  return o;
}

std::string UsageText()
{
  return R"(usage: precisemc [INPUT] [options]

Extracts the isosurface of a volume with vtkPreciseMarchingCubes: Marching
Cubes with the topology of the trilinear interpolant, refined adaptively
onto the trilinear isosurface. Prints a table of each run.

INPUT is a volume file (.vti, legacy .vtk structured points, .mha/.mhd,
.nii/.nii.gz, .nrrd/.nhdr) or a directory holding a DICOM series. Without
INPUT the built-in samples are used (as with --sample all).

options:
  -v, --value V         isovalue (repeatable; the surfaces are appended).
                        Default: the sample's isovalue, or for a file the
                        middle of its scalar range
      --array NAME      the input's point array to contour (default: its
                        active scalars, else its first point array)
      --sample NAME     built-in volume: tube, atoms, ml or all
      --epsilon E       largest distance of a triangle's sample points to
                        the trilinear isosurface (or --filter's), in
                        cells; 0 = plain Marching Cubes (default 0.01)
      --max-level L     maximum refinement level, 0..10 (default 5)
      --rule R          refinement rule A, A1, A2 or B (default A1)
      --topology T      trilinear or classic (vtkMarchingCubes's table);
                        default trilinear
      --filter F        reconstruction filter refinement follows: trilinear
                        (default), catmull-rom, bspline (smoothing) or
                        bspline-interpolating; --epsilon is then measured
                        to that filter's isosurface (--measure still
                        measures to the trilinear S_K)
      --normals N       point normals: none, gradient (of the trilinear
                        interpolant) or central (differences); default
                        gradient
      --gradients       also a point array "Gradients" (.vtp output): the
                        scalar gradient, towards higher values, in value
                        per world length, computed as the normals are
                        (gradient with --normals none)
      --max-triangles N cap on the output triangles of each isovalue:
                        refinement stops at the deepest level that fits
                        (the Marching Cubes triangles are always kept);
                        0 = no cap (default)
      --threads N       worker threads (also of --measure); 0 = all cores
                        (default)
      --smp             run the library's work as vtkSMPTools tasks, on
                        VTK's SMP backend (VTK_SMP_BACKEND_IN_USE), with
                        --threads N of them when N > 0 (at most the
                        number of cores); same output
  -o, --output FILE     write the surface: .vtp, .ply, .stl or .obj. With
                        several volumes (--sample all), one file each:
                        FILE with "-<sample>" before the extension
      --compare PNG     picture of vtkMarchingCubes (left) beside PreciseMC
                        (right), one row per volume
      --distance PNG    picture of the Marching Cubes surface coloured by
                        its distance to the refined surface
      --write-volume VTI
                        also write the volume contoured (a sample, or the
                        input as read) as .vti; with several volumes one
                        file each, like -o
      --measure         add to the table the distance of vtkMarchingCubes's
                        surface and of PreciseMC's surface to the trilinear
                        isosurface S_K (max and area-weighted mean, in
                        cells), measured independently of the refinement
                        (certified to 1e-5 cells + 2 %)
      --measure-density D
                        subdivisions per triangle edge for --measure
                        (D+1 points on an edge), 1..64: (D+1)(D+2)/2
                        points per triangle (default 3;
                        lower it for large surfaces; 1 measures only the
                        vertices, which every contour filter puts on S_K)
  -q, --quiet           print nothing but errors (and the warning that a
                        surface is empty)
  -h, --help            print this help
      --version         print the version

Pictures are rendered off screen; without a usable $DISPLAY (one that
opens and has GLX) the tool starts a private Xvfb. Files are written
through temporary files, renamed once the whole run has succeeded, so a
failed run leaves no output; an output that is a symbolic link is written
through (the link stays), one that is not a regular file (a FIFO, a
device) is refused. On error, one line "precisemc: error: ..." goes to
stderr and the exit status is 1 (2 for a command-line mistake).
)";
}

}
