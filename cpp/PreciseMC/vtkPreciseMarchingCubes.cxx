/*=========================================================================

  Program:   PreciseMC
  Module:    vtkPreciseMarchingCubes.cxx

  Copyright (c) the PreciseMC authors
  All rights reserved.
  Licensed under the MIT or Apache-2.0 license, at your option.

     This software is distributed WITHOUT ANY WARRANTY; without even
     the implied warranty of MERCHANTABILITY or FITNESS FOR A PARTICULAR
     PURPOSE.

=========================================================================*/
#include "vtkPreciseMarchingCubes.h"

#include "vtkCellArray.h"
#include "vtkCellData.h"
#include "vtkCompositeDataSet.h"
#include "vtkDataArray.h"
#include "vtkDataSetAttributes.h"
#include "vtkDoubleArray.h"
#include "vtkExecutive.h"
#include "vtkExtentTranslator.h"
#include "vtkFloatArray.h"
#include "vtkIdList.h"
#include "vtkIdTypeArray.h"
#include "vtkImageData.h"
#include "vtkInformation.h"
#include "vtkInformationIntegerRequestKey.h"
#include "vtkInformationVector.h"
#include "vtkMath.h"
#include "vtkMatrix3x3.h"
#include "vtkMatrix4x4.h"
#include "vtkNew.h"
#include "vtkObjectFactory.h"
#include "vtkPointData.h"
#include "vtkPoints.h"
#include "vtkPolyData.h"
#include "vtkSMPTools.h"
#include "vtkSmartPointer.h"
#include "vtkStreamingDemandDrivenPipeline.h"
#include "vtkUnsignedCharArray.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <functional>
#include <limits>
#include <memory>
#include <new>
#include <string>
#include <system_error>
#include <thread>
#include <vector>

extern "C"
{
#include "precisemc.h"
}

// The clamp of SetNumberOfThreads (the header does not include the C API).
static_assert(PMC_MAX_THREADS == 4096, "update vtkPreciseMarchingCubes::SetNumberOfThreads");

#ifdef __linux__
#include <sys/mman.h>
#endif

vtkStandardNewMacro(vtkPreciseMarchingCubes);

//------------------------------------------------------------------------------
// Helpers around the C API: owning handles, type mapping, progress.
namespace
{
// VTK answers an output allocation that fails by throwing std::bad_alloc
// on some paths and, on others, with an error and an array left short:
// the second becomes the first, which RequestData() reports.
void RequireLength(vtkIdType have, vtkIdType want)
{
  if (have != want)
  {
    throw std::bad_alloc();
  }
}

// Ghost samples the cubic filters read around a piece. One is what the
// piece's own cells need; the second gives the ghost cells next to the
// piece their whole 4x4x4 neighbourhood, so they compute what the serial
// run computes there: their points on the piece's faces weld as in the
// serial run, and a triangle lying flat in such a face meets its
// duplicate from the ghost side and is removed as in the serial run.
constexpr int CubicGhostSamples = 2;

// Ghost samples a piece is contoured with, whose cells' triangles are not
// output: the cubic filters' (above); with the trilinear filter, one when
// refinement may mesh a cell again on sub-cells (trilinear topology, max
// level 3 up): such a cell joins its fine outline to the old one by a
// strip in each face, and where the cell across the face is meshed again
// too the two strips cancel, in the serial run, which a piece sees only
// with the cells across its faces; and one for normals or gradients
// (`derivatives`), whose gradient at a point on the piece's face takes the
// cell (or the samples) beyond it, as the serial run does. Otherwise none:
// image pieces share their boundary samples, all the trilinear filter's
// surface needs, except where samples equal the isovalue (see
// ContourGhostSamples()).
int GhostSamples(
  int reconstruction, int topology, double epsilon, int maxLevel, bool derivatives)
{
  if (reconstruction != vtkPreciseMarchingCubes::RECONSTRUCTION_TRILINEAR)
  {
    return CubicGhostSamples;
  }
  const bool subcells = topology == vtkPreciseMarchingCubes::TOPOLOGY_TRILINEAR &&
    epsilon > 0.0 && maxLevel >= 3;
  return subcells || derivatives ? 1 : 0;
}

// Ghost samples a piece is asked for and contoured with: those the run
// reads (GhostSamples()), and at least one. Where a plane of samples equals
// the isovalue, the cells on its two sides emit the same flat triangles with
// opposite orientations, and the serial run cancels the pairs; a piece cut
// along that plane cancels its copy only when it holds the cell across the
// cut too (without it, the pieces' union had a double-sided sheet there
// that the serial surface has not).
int ContourGhostSamples(
  int reconstruction, int topology, double epsilon, int maxLevel, bool derivatives)
{
  return std::max(1, GhostSamples(reconstruction, topology, epsilon, maxLevel, derivatives));
}

// Whether `dataExtent` is piece `piece` of `pieces` of `splitExtent`, as
// vtkExtentTranslator cuts it in `splitMode` (without ghost levels: an
// input that holds ghost levels has ghost arrays, which tell its own cells
// instead; see OwnCells()).
bool SplitAsAsked(
  const int dataExtent[6], int piece, int pieces, const int splitExtent[6], int splitMode)
{
  vtkNew<vtkExtentTranslator> translator;
  int extent[6];
  return translator->PieceToExtentThreadSafe(
           piece, pieces, 0, const_cast<int*>(splitExtent), extent, splitMode, 0) &&
    std::equal(extent, extent + 6, dataExtent);
}

// The point extent of the cells of an image of `cells` cells per axis
// (from `dataExtent`) that `duplicate(i, j, k)` does not mark as another
// piece's, into `box`; false when it marks every cell.
template <typename Duplicate>
bool OwnBox(const int dataExtent[6], const vtkIdType cells[3], Duplicate duplicate, int box[6])
{
  vtkIdType lo[3] = { cells[0], cells[1], cells[2] };
  vtkIdType hi[3] = { -1, -1, -1 };
  for (vtkIdType k = 0; k < cells[2]; ++k)
  {
    for (vtkIdType j = 0; j < cells[1]; ++j)
    {
      for (vtkIdType i = 0; i < cells[0]; ++i)
      {
        if (!duplicate(i, j, k))
        {
          const vtkIdType at[3] = { i, j, k };
          for (int d = 0; d < 3; ++d)
          {
            lo[d] = std::min(lo[d], at[d]);
            hi[d] = std::max(hi[d], at[d]);
          }
        }
      }
    }
  }
  if (hi[0] < 0)
  {
    return false;
  }
  for (int d = 0; d < 3; ++d)
  {
    box[2 * d] = dataExtent[2 * d] + static_cast<int>(lo[d]);
    box[2 * d + 1] = dataExtent[2 * d] + static_cast<int>(hi[d]) + 1;
  }
  return true;
}

// The cells per axis of an image of extent `dataExtent`.
void CellCounts(const int dataExtent[6], vtkIdType cells[3])
{
  for (int i = 0; i < 3; ++i)
  {
    cells[i] = static_cast<vtkIdType>(dataExtent[2 * i + 1]) - dataExtent[2 * i];
  }
}

// The point extent of the cells of `input` (extent `dataExtent`) that its
// cell ghost array does not mark as duplicates, into `piece` (the whole
// `dataExtent` without such an array); false when every cell is a ghost.
// For an input that arrives split otherwise than the filter asked (an
// upstream filter that splits the volume its own way, as Resample To
// Image does): the pieces' own cells then still cover the volume once,
// where cropping to the piece asked for left a slab between two pieces
// that neither contoured.
bool OwnCells(vtkImageData* input, const int dataExtent[6], int piece[6])
{
  std::copy(dataExtent, dataExtent + 6, piece);
  vtkUnsignedCharArray* ghosts = input->GetCellGhostArray();
  vtkIdType cells[3];
  CellCounts(dataExtent, cells);
  if (!ghosts || cells[0] < 1 || cells[1] < 1 || cells[2] < 1 ||
    ghosts->GetNumberOfTuples() != cells[0] * cells[1] * cells[2])
  {
    return true;
  }
  const unsigned char* flag = ghosts->GetPointer(0);
  return OwnBox(
    dataExtent, cells,
    [&](vtkIdType i, vtkIdType j, vtkIdType k) {
      return (flag[i + cells[0] * (j + cells[1] * k)] & vtkDataSetAttributes::DUPLICATECELL) != 0;
    },
    piece);
}

// The point extent of the cells of `input` (extent `dataExtent`) none of
// whose corners its point ghost array marks as duplicates, into `box`;
// false when the input has a cell ghost array (OwnCells() reads that), no
// point ghost array marking a duplicate, or no such cell. For a piece that
// arrives grown by the ghost levels asked for but with the point ghost
// array only (vtkImageChangeInformation and vtkImageTranslateExtent pass
// the point data on, not the cell data): VTK marks the points outside the
// piece's own extent, so a cell with such a corner is another piece's.
bool OwnCellsByPoints(vtkImageData* input, const int dataExtent[6], int box[6])
{
  vtkUnsignedCharArray* ghosts = input->GetPointGhostArray();
  if (input->GetCellGhostArray() || !ghosts || ghosts->GetNumberOfComponents() != 1)
  {
    return false;
  }
  vtkIdType cells[3];
  CellCounts(dataExtent, cells);
  if (cells[0] < 1 || cells[1] < 1 || cells[2] < 1 ||
    ghosts->GetNumberOfTuples() != (cells[0] + 1) * (cells[1] + 1) * (cells[2] + 1))
  {
    return false;
  }
  const unsigned char* flag = ghosts->GetPointer(0);
  const vtkIdType points = ghosts->GetNumberOfTuples();
  if (std::none_of(flag, flag + points,
        [](unsigned char f) { return (f & vtkDataSetAttributes::DUPLICATEPOINT) != 0; }))
  {
    return false;
  }
  auto duplicate = [&](vtkIdType i, vtkIdType j, vtkIdType k) {
    return (flag[i + (cells[0] + 1) * (j + (cells[1] + 1) * k)] &
             vtkDataSetAttributes::DUPLICATEPOINT) != 0;
  };
  return OwnBox(
    dataExtent, cells,
    [&](vtkIdType i, vtkIdType j, vtkIdType k) {
      return duplicate(i, j, k) || duplicate(i + 1, j, k) || duplicate(i, j + 1, k) ||
        duplicate(i + 1, j + 1, k) || duplicate(i, j, k + 1) || duplicate(i + 1, j, k + 1) ||
        duplicate(i, j + 1, k + 1) || duplicate(i + 1, j + 1, k + 1);
    },
    box);
}

// Whether a request for the update extent is the one a composite input's
// pipeline (vtkCompositeDataPipeline) makes of a block, run as an input of
// its own: the algorithm alone is called, after the composite input was
// asked for all the blocks (the pipeline's own update passes call the
// algorithm before forwarding the request upstream). The input's
// information is then the composite input's: what is set there stays for
// the next update.
bool IsBlockRequest(vtkInformation* request)
{
  return request && request->Has(vtkExecutive::ALGORITHM_AFTER_FORWARD()) &&
    !request->Has(vtkExecutive::ALGORITHM_BEFORE_FORWARD());
}

// Whether the input's cell ghost array marks any cell as a duplicate of
// another piece's.
bool HasDuplicateCells(vtkImageData* input)
{
  vtkUnsignedCharArray* ghosts = input->GetCellGhostArray();
  if (!ghosts)
  {
    return false;
  }
  const unsigned char* flag = ghosts->GetPointer(0);
  const vtkIdType n = ghosts->GetNumberOfTuples() * ghosts->GetNumberOfComponents();
  return std::any_of(
    flag, flag + n, [](unsigned char f) { return (f & vtkDataSetAttributes::DUPLICATECELL) != 0; });
}

// Asks Linux for transparent huge pages behind a large output array that
// nothing has written yet (where THP is in `madvise` mode): filling it
// otherwise takes a page fault per 4 KiB, a good part of the copy's time.
// Advice only; as in the library, PMC_NO_HUGE_PAGES=1 turns it off.
void AdviseHugePages(void* data, size_t bytes)
{
#ifdef __linux__
  static const bool off = [] {
    const char* v = std::getenv("PMC_NO_HUGE_PAGES");
    return v && std::string(v) != "0";
  }();
  const std::uintptr_t huge = std::uintptr_t(2) << 20;
  const std::uintptr_t start = reinterpret_cast<std::uintptr_t>(data);
  const std::uintptr_t lo = (start + huge - 1) & ~(huge - 1);
  const std::uintptr_t hi = (start + bytes) & ~(huge - 1);
  if (!off && data && hi > lo)
  {
    madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_HUGEPAGE);
  }
#else
  (void)data;
  (void)bytes;
#endif
}

// Whether an extent holds no sample (VTK's empty extent is 0, -1, ...).
bool IsEmptyExtent(const int extent[6])
{
  return extent[0] > extent[1] || extent[2] > extent[3] || extent[4] > extent[5];
}

// Extent index `i + d`, held to int's range: an extent may reach INT_MAX,
// and the extents it is compared with lie within that range anyway.
int ShiftedIndex(int i, int d)
{
  const long long v = static_cast<long long>(i) + d;
  return static_cast<int>(std::max<long long>(
    std::numeric_limits<int>::min(), std::min<long long>(std::numeric_limits<int>::max(), v)));
}

// The library's executor on vtkSMPTools: every task a separate index, so
// that the backend balances the tasks (slabs of cell layers, chunks of
// points) one by one. The tasks never throw.
//
// The library reports progress, and learns of AbortExecute, after the
// tasks it runs on the calling thread. TBB runs some of a For's range on
// the calling thread; the STDThread backend runs none there (the caller
// only waits, and a long refinement went without progress events, deaf
// to AbortExecute, to its end). On that backend the calling thread takes
// tasks too: it runs the first one and then, next to a For over the other
// workers started from a helper thread, takes the others from a shared
// counter with them.
void SMPExecutor(void*, uint64_t count, pmc_task_fn task, void* taskData)
{
  // No C++ exception may leave this function: it is called from the
  // library's (Rust) frames, where one would abort the process. Where
  // vtkSMPTools throws (std::bad_alloc), the tasks it did not run are left
  // undone, which the library reports as an executor error.
  const int workers = vtkSMPTools::GetEstimatedNumberOfThreads();
  if (count < 2 || workers < 2 || std::string(vtkSMPTools::GetBackend()) != "STDThread")
  {
    try
    {
      vtkSMPTools::For(0, static_cast<vtkIdType>(count), 1,
        [task, taskData](vtkIdType b, vtkIdType e) {
          for (vtkIdType i = b; i < e; ++i)
          {
            task(taskData, static_cast<uint64_t>(i));
          }
        });
    }
    catch (...)
    {
    }
    return;
  }
  std::atomic<uint64_t> next(1);
  auto drain = [&next, count, task, taskData]() {
    for (uint64_t i = next.fetch_add(1); i < count; i = next.fetch_add(1))
    {
      task(taskData, i);
    }
  };
  const vtkIdType others = static_cast<vtkIdType>(
    std::min<uint64_t>(static_cast<uint64_t>(workers - 1), count - 1));
  std::thread helper;
  try
  {
    helper = std::thread([&drain, others]() {
      try
      {
        vtkSMPTools::For(0, others, 1, [&drain](vtkIdType, vtkIdType) { drain(); });
      }
      catch (...)
      {
        // The calling thread drains what is left.
      }
    });
  }
  catch (...)
  {
    // No thread to be had (std::system_error, std::bad_alloc): the calling
    // thread runs every task.
  }
  task(taskData, 0);
  drain();
  if (helper.joinable())
  {
    helper.join();
  }
}

struct OptionsDeleter
{
  void operator()(pmc_options* o) const { pmc_options_free(o); }
};
using OptionsPtr = std::unique_ptr<pmc_options, OptionsDeleter>;

struct MeshDeleter
{
  void operator()(pmc_mesh* m) const { pmc_mesh_free(m); }
};
using MeshPtr = std::unique_ptr<pmc_mesh, MeshDeleter>;

// The message of the last failed call on this thread, with its status.
std::string LastError(pmc_status status)
{
  std::string message;
  char buffer[1024];
  size_t n = pmc_last_error_message(buffer, sizeof(buffer));
  if (n > 0)
  {
    if (n >= sizeof(buffer))
    {
      // Truncated: ask again with room for everything.
      std::vector<char> large(n + 1);
      pmc_last_error_message(large.data(), large.size());
      message = large.data();
    }
    else
    {
      message = buffer;
    }
  }
  const char* name = pmc_status_string(status);
  std::string result = name ? name : "unknown status";
  if (!message.empty())
  {
    result += ": " + message;
  }
  return result;
}

// What the progress callback needs: the filter and the part of the whole
// execution the current call covers.
struct ProgressState
{
  vtkPreciseMarchingCubes* Self;
  double Base;
  double Span;
  // What an observer of the progress event threw: kept, the extraction
  // stopped, and rethrown once pmc_extract has returned (an exception
  // must not unwind through the library's frames, where it would abort
  // the process).
  std::exception_ptr Thrown;
};

// Called by pmc_extract on the calling thread; a non-zero return aborts.
int ProgressCallback(void* userData, double fraction)
{
  ProgressState* state = static_cast<ProgressState*>(userData);
  try
  {
    state->Self->UpdateProgress(state->Base + state->Span * fraction);
  }
  catch (...)
  {
    state->Thrown = std::current_exception();
    return 1;
  }
  return state->Self->GetAbortExecute() ? 1 : 0;
}

// Inverse transpose of a 3x3 matrix (row-major), for normals.
bool InverseTranspose(const double m[3][3], double r[3][3])
{
  double inv[3][3];
  double det = vtkMath::Determinant3x3(m);
  if (det == 0.0 || !std::isfinite(det))
  {
    return false;
  }
  vtkMath::Invert3x3(m, inv);
  vtkMath::Transpose3x3(inv, r);
  return true;
}

// The part of a mesh that is output: every point and triangle, or (when
// the library contoured a ghost layer too) the triangles of the contoured
// cells and the points they use.
struct MeshSelection
{
  bool All = true;
  vtkTypeUInt64 NumberOfPoints = 0;
  vtkTypeUInt64 NumberOfTriangles = 0;
  std::vector<vtkIdType> PointMap;  // new index of each point, -1 if dropped
  std::vector<vtkIdType> Triangles; // indices of the kept triangles
};

// Keeps the triangles of the cells of `extent` (point extent, global
// indices) out of a mesh contoured on `sampleExtent`, which may hold a
// layer of ghost cells around it. Every triangle lies in the closed cell
// that made it; its cell along each axis is taken as the floor of the
// smallest vertex coordinate. The vertices are computed in global index
// coordinates, bit-identically by every piece, so pieces sharing a face
// assign each triangle to the same cell: the union of the pieces is the
// serial mesh, each triangle exactly once. Triangles beyond the extent on
// a side without ghost cells (flat in the volume's last face) are kept.
// With `hidden` (the cell ghost flags of the input's cells, extent
// `dataExtent`), the triangles of cells flagged HIDDENCELL are dropped too.
void SelectCells(const pmc_mesh* mesh, const int extent[6], const int sampleExtent[6],
  const unsigned char* hidden, const int dataExtent[6], MeshSelection& selection)
{
  const vtkIdType np = static_cast<vtkIdType>(pmc_mesh_point_count(mesh));
  const vtkIdType nt = static_cast<vtkIdType>(pmc_mesh_triangle_count(mesh));
  const double* ijk = pmc_mesh_index_points(mesh);
  const int64_t* tris = pmc_mesh_triangles(mesh);
  selection.All = false;
  selection.PointMap.assign(static_cast<size_t>(np), -1);
  selection.Triangles.clear();
  for (vtkIdType t = 0; t < nt; ++t)
  {
    const int64_t* tri = tris + 3 * t;
    bool keep = true;
    vtkIdType hiddenId = 0; // the triangle's cell among the input's
    vtkIdType stride = 1;
    for (int d = 0; d < 3 && keep; ++d)
    {
      const double lowest =
        std::min(ijk[3 * tri[0] + d], std::min(ijk[3 * tri[1] + d], ijk[3 * tri[2] + d]));
      const double cell = std::floor(lowest);
      if (extent[2 * d] > sampleExtent[2 * d] && cell < extent[2 * d])
      {
        keep = false;
      }
      else if (extent[2 * d + 1] < sampleExtent[2 * d + 1] && cell >= extent[2 * d + 1])
      {
        keep = false;
      }
      if (hidden)
      {
        // A triangle in the volume's last face belongs to the last cell.
        const double c = std::max(static_cast<double>(dataExtent[2 * d]),
          std::min(cell, static_cast<double>(dataExtent[2 * d + 1] - 1)));
        hiddenId += (static_cast<vtkIdType>(c) - dataExtent[2 * d]) * stride;
        stride *= static_cast<vtkIdType>(dataExtent[2 * d + 1]) - dataExtent[2 * d];
      }
    }
    if (keep && hidden && (hidden[hiddenId] & vtkDataSetAttributes::HIDDENCELL) != 0)
    {
      keep = false;
    }
    if (keep)
    {
      selection.Triangles.push_back(t);
      for (int v = 0; v < 3; ++v)
      {
        selection.PointMap[static_cast<size_t>(tri[v])] = 0;
      }
    }
  }
  vtkIdType next = 0;
  for (vtkIdType& p : selection.PointMap)
  {
    if (p == 0)
    {
      p = next++;
    }
  }
  selection.NumberOfPoints = static_cast<vtkTypeUInt64>(next);
  selection.NumberOfTriangles = static_cast<vtkTypeUInt64>(selection.Triangles.size());
}

} // anonymous namespace

//------------------------------------------------------------------------------
// Construct with a single contour value of 0.0, normals and scalars on,
// gradients off,
// refinement with epsilon 0.01 up to level 5 (rule A1), trilinear topology.
vtkPreciseMarchingCubes::vtkPreciseMarchingCubes()
{
  this->ContourValues = vtkContourValues::New();
  this->ComputeNormals = 1;
  this->ComputeGradients = 0;
  this->ComputeScalars = 1;
  this->InterpolateAttributes = 0;
  this->ComputeLevels = 0;
  this->ArrayComponent = 0;
  this->OutputPointsPrecision = vtkAlgorithm::DEFAULT_PRECISION;

  this->Epsilon = 0.01;
  this->MaxLevel = 5;
  this->Rule = RULE_A1;
  this->ReconstructionFilter = RECONSTRUCTION_TRILINEAR;
  this->Topology = TOPOLOGY_TRILINEAR;
  this->NormalMode = NORMALS_GRADIENT;
  this->MaxTriangles = 0;
  this->NumberOfThreads = 0;
  this->UseSMPTools = 0;

  this->NumberOfExecutions = 0;
  this->ResetStatistics();
  this->HasContourExtent = false;
  this->ContourWholeUnknown = false;
  for (int i = 0; i < 3; ++i)
  {
    this->ContourExtent[2 * i] = VTK_INT_MAX;
    this->ContourExtent[2 * i + 1] = VTK_INT_MIN;
    this->ContourSplitExtent[2 * i] = VTK_INT_MAX;
    this->ContourSplitExtent[2 * i + 1] = VTK_INT_MIN;
  }
  this->ContourPiece = 0;
  this->ContourPieces = 1;
  this->CompositePieces = 1;
  this->ContourSplitMode = vtkExtentTranslator::BLOCK_MODE;
  this->WholeInputShare = WHOLE_INPUT_AS_ASKED;

  // By default process active point scalars.
  this->SetInputArrayToProcess(
    0, 0, 0, vtkDataObject::FIELD_ASSOCIATION_POINTS, vtkDataSetAttributes::SCALARS);
}

//------------------------------------------------------------------------------
vtkPreciseMarchingCubes::~vtkPreciseMarchingCubes()
{
  this->ContourValues->Delete();
}

//------------------------------------------------------------------------------
int vtkPreciseMarchingCubes::LibraryScalarType(int vtkType)
{
  switch (vtkType)
  {
    case VTK_CHAR:
      return std::numeric_limits<char>::is_signed ? PMC_SCALAR_TYPE_I8 : PMC_SCALAR_TYPE_U8;
    case VTK_SIGNED_CHAR:
      return PMC_SCALAR_TYPE_I8;
    case VTK_UNSIGNED_CHAR:
      return PMC_SCALAR_TYPE_U8;
    case VTK_SHORT:
      return PMC_SCALAR_TYPE_I16;
    case VTK_UNSIGNED_SHORT:
      return PMC_SCALAR_TYPE_U16;
    case VTK_INT:
      return PMC_SCALAR_TYPE_I32;
    case VTK_UNSIGNED_INT:
      return PMC_SCALAR_TYPE_U32;
    case VTK_LONG:
      return sizeof(long) == 8 ? PMC_SCALAR_TYPE_I64 : PMC_SCALAR_TYPE_I32;
    case VTK_UNSIGNED_LONG:
      return sizeof(unsigned long) == 8 ? PMC_SCALAR_TYPE_U64 : PMC_SCALAR_TYPE_U32;
    case VTK_LONG_LONG:
      return PMC_SCALAR_TYPE_I64;
    case VTK_UNSIGNED_LONG_LONG:
      return PMC_SCALAR_TYPE_U64;
    case VTK_ID_TYPE:
      return sizeof(vtkIdType) == 8 ? PMC_SCALAR_TYPE_I64 : PMC_SCALAR_TYPE_I32;
    case VTK_FLOAT:
      return PMC_SCALAR_TYPE_F32;
    case VTK_DOUBLE:
      return PMC_SCALAR_TYPE_F64;
    default:
      return -1;
  }
}

//------------------------------------------------------------------------------
vtkTypeUInt64 vtkPreciseMarchingCubes::ReleaseRetainedMemory()
{
  return static_cast<vtkTypeUInt64>(pmc_release_memory());
}

//------------------------------------------------------------------------------
// Overload standard modified time function. If contour values are modified,
// then this object is modified as well.
vtkMTimeType vtkPreciseMarchingCubes::GetMTime()
{
  vtkMTimeType mTime = this->Superclass::GetMTime();
  vtkMTimeType mTime2 = this->ContourValues->GetMTime();
  return (mTime2 > mTime ? mTime2 : mTime);
}

//------------------------------------------------------------------------------
void vtkPreciseMarchingCubes::ResetStatistics()
{
  this->NumberOfMCTriangles = 0;
  this->NumberOfRefinedTriangles = 0;
  this->NumberOfAmbiguousCells = 0;
  this->NumberOfSkippedCells = 0;
  this->MaxLevelReached = 0;
  this->MeanLevel = 0.0;
  this->NumberOfSamplesEvaluated = 0;
  this->NumberOfSplitPoints = 0;
  this->NumberOfProjectionFailures = 0;
  this->NumberOfFacesAboveEpsilon = 0;
  this->NumberOfCellsRefinedOnFacesOnly = 0;
  this->NumberOfRecutPolygons = 0;
  this->NumberOfCellsOnSubcells = 0;
  this->BudgetReached = false;
  this->ExecutionTime = 0.0;
}

//------------------------------------------------------------------------------
int vtkPreciseMarchingCubes::ClampSetting(const char* name, int value, int lo, int hi)
{
  if (value >= lo && value <= hi)
  {
    return value;
  }
  const int clamped = value < lo ? lo : hi;
  vtkWarningMacro(<< name << " " << value << " is outside " << lo << ".." << hi << ": using "
                  << clamped);
  return clamped;
}

// The setters of vtkSetClampMacro, but not silent: an out-of-range value
// warns (see ClampSetting). Modified() only when the value changes, as
// there.
#define PMC_CLAMPED_SETTER(name, lo, hi)                                                           \
  void vtkPreciseMarchingCubes::Set##name(int value)                                               \
  {                                                                                                \
    const int clamped = this->ClampSetting(#name, value, lo, hi);                                  \
    if (this->name != clamped)                                                                     \
    {                                                                                              \
      this->name = clamped;                                                                        \
      this->Modified();                                                                            \
    }                                                                                              \
  }

PMC_CLAMPED_SETTER(OutputPointsPrecision, SINGLE_PRECISION, DEFAULT_PRECISION)
PMC_CLAMPED_SETTER(MaxLevel, 0, 10)
PMC_CLAMPED_SETTER(Rule, RULE_A, RULE_B)
PMC_CLAMPED_SETTER(
  ReconstructionFilter, RECONSTRUCTION_TRILINEAR, RECONSTRUCTION_BSPLINE_INTERPOLATING)
PMC_CLAMPED_SETTER(Topology, TOPOLOGY_TRILINEAR, TOPOLOGY_CLASSIC)
PMC_CLAMPED_SETTER(NormalMode, NORMALS_GRADIENT, NORMALS_CENTRAL_DIFFERENCE)
PMC_CLAMPED_SETTER(NumberOfThreads, 0, 4096)

#undef PMC_CLAMPED_SETTER

//------------------------------------------------------------------------------
const char* vtkPreciseMarchingCubes::GetRuleAsString()
{
  switch (this->Rule)
  {
    case RULE_A:
      return "A";
    case RULE_A1:
      return "A1";
    case RULE_A2:
      return "A2";
    case RULE_B:
      return "B";
    default:
      return "Unknown";
  }
}

//------------------------------------------------------------------------------
const char* vtkPreciseMarchingCubes::GetReconstructionFilterAsString()
{
  switch (this->ReconstructionFilter)
  {
    case RECONSTRUCTION_TRILINEAR:
      return "Trilinear";
    case RECONSTRUCTION_CATMULL_ROM:
      return "CatmullRom";
    case RECONSTRUCTION_BSPLINE:
      return "BSpline";
    case RECONSTRUCTION_BSPLINE_INTERPOLATING:
      return "BSplineInterpolating";
    default:
      return "Unknown";
  }
}

//------------------------------------------------------------------------------
const char* vtkPreciseMarchingCubes::GetTopologyAsString()
{
  return this->Topology == TOPOLOGY_CLASSIC ? "Classic" : "Trilinear";
}

//------------------------------------------------------------------------------
const char* vtkPreciseMarchingCubes::GetNormalModeAsString()
{
  return this->NormalMode == NORMALS_CENTRAL_DIFFERENCE ? "CentralDifference" : "Gradient";
}

//------------------------------------------------------------------------------
int vtkPreciseMarchingCubes::RequestData(vtkInformation* vtkNotUsed(request),
  vtkInformationVector** inputVector, vtkInformationVector* outputVector)
{
  // The library reports its own memory running out; the output's VTK
  // arrays and vectors throw std::bad_alloc instead, which would abort the
  // host application (a ParaView session) if it left this method. An
  // exception of a progress observer (see ProgressCallback) is reported
  // here too: thrown on through VTK's executive, it would leave the
  // pipeline unable to update again.
  const auto fail = [this, outputVector](const std::string& why) {
    this->ResetStatistics();
    if (vtkPolyData* output = vtkPolyData::GetData(outputVector))
    {
      output->Initialize();
    }
    vtkErrorMacro(<< why << "; the output is empty.");
    return 1;
  };
  try
  {
    return this->Contour(inputVector, outputVector);
  }
  catch (const std::bad_alloc&)
  {
    return fail("Out of memory while building the output");
  }
  catch (const std::exception& e)
  {
    return fail(std::string("An exception stopped the run: ") + e.what());
  }
  catch (...)
  {
    return fail("An exception of unknown type stopped the run");
  }
}

//------------------------------------------------------------------------------
int vtkPreciseMarchingCubes::Contour(
  vtkInformationVector** inputVector, vtkInformationVector* outputVector)
{
  vtkInformation* inInfo = inputVector[0]->GetInformationObject(0);
  vtkInformation* outInfo = outputVector->GetInformationObject(0);
  vtkImageData* input = vtkImageData::SafeDownCast(inInfo->Get(vtkDataObject::DATA_OBJECT()));
  vtkPolyData* output = vtkPolyData::SafeDownCast(outInfo->Get(vtkDataObject::DATA_OBJECT()));

  this->ResetStatistics();
  if (output == nullptr)
  {
    vtkErrorMacro(<< "Output is not a vtkPolyData.");
    return 1;
  }
  output->Initialize();
  if (input == nullptr)
  {
    vtkErrorMacro(<< "Input is not a vtkImageData.");
    return 1;
  }

  vtkDebugMacro(<< "Executing precise marching cubes");

  // Check the input: nothing to do on an empty image or without values.
  // A copy: a progress observer may change the contour values while this
  // runs, which reallocates the array the list holds.
  const vtkIdType numContours = this->ContourValues->GetNumberOfContours();
  const double* listed = this->ContourValues->GetValues();
  const std::vector<double> values(listed, listed + (numContours > 0 ? numContours : 0));
  // An extent whose point count overflows vtkIdType (or whose length
  // overflows an int) reads as empty or negative: say so rather than
  // return nothing.
  {
    int ext[6];
    input->GetExtent(ext);
    if (ext[0] <= ext[1] && ext[2] <= ext[3] && ext[4] <= ext[5])
    {
      double points = 1.0;
      for (int i = 0; i < 3; ++i)
      {
        points *= static_cast<double>(ext[2 * i + 1]) - static_cast<double>(ext[2 * i]) + 1.0;
      }
      if (points > static_cast<double>(VTK_ID_MAX) ||
        static_cast<double>(input->GetNumberOfPoints()) != points)
      {
        vtkErrorMacro(<< "The input's extent (" << ext[0] << ", " << ext[1] << ", " << ext[2]
                      << ", " << ext[3] << ", " << ext[4] << ", " << ext[5] << ") holds " << points
                      << " points, more than vtkImageData can count");
        return 1;
      }
    }
  }
  if (input->GetNumberOfPoints() < 1 || numContours < 1)
  {
    vtkDebugMacro(<< "Empty input or no contour values");
    return 1;
  }

  int association = vtkDataObject::FIELD_ASSOCIATION_POINTS;
  vtkDataArray* inScalars = this->GetInputArrayToProcess(0, inputVector, association);
  if (inScalars == nullptr)
  {
    // An array that is there but holds no numbers (strings, variants) is
    // not a data array: name it rather than say there is none.
    int anyAssociation = vtkDataObject::FIELD_ASSOCIATION_POINTS;
    vtkAbstractArray* any = this->GetInputAbstractArrayToProcess(0, inputVector, anyAssociation);
    if (any != nullptr)
    {
      vtkErrorMacro(<< "Unsupported scalar type " << any->GetDataTypeAsString() << " of array "
                    << (any->GetName() ? any->GetName() : "(unnamed)")
                    << ": integer and floating point arrays are supported");
      return 1;
    }
    // An array sought among the cells' or the field's arrays (and not
    // found there): only point data can be contoured, whatever the name.
    vtkInformation* chosen = this->GetInputArrayInformation(0);
    const int asked = chosen && chosen->Has(vtkDataObject::FIELD_ASSOCIATION())
      ? chosen->Get(vtkDataObject::FIELD_ASSOCIATION())
      : vtkDataObject::FIELD_ASSOCIATION_POINTS;
    if (asked != vtkDataObject::FIELD_ASSOCIATION_POINTS &&
      asked != vtkDataObject::FIELD_ASSOCIATION_POINTS_THEN_CELLS)
    {
      vtkErrorMacro(<< "The array to contour is sought among the input's "
                    << (asked == vtkDataObject::FIELD_ASSOCIATION_CELLS ? "cell" : "non-point")
                    << " data (association " << asked
                    << "), but only point data can be contoured: select it with "
                       "FIELD_ASSOCIATION_POINTS");
      return 1;
    }
    // An array chosen by a name the input lacks (ParaView's Contour By):
    // name it and what there is.
    const char* wanted = chosen && chosen->Has(vtkDataObject::FIELD_NAME())
      ? chosen->Get(vtkDataObject::FIELD_NAME())
      : nullptr;
    if (wanted && *wanted)
    {
      std::string names;
      vtkPointData* pd = input->GetPointData();
      for (int i = 0; i < pd->GetNumberOfArrays(); ++i)
      {
        const char* n = pd->GetArrayName(i);
        if (n && std::strcmp(n, vtkDataSetAttributes::GhostArrayName()) == 0)
        {
          continue; // the pipeline's, never contoured
        }
        names += std::string(names.empty() ? "" : ", ") + (n ? n : "(unnamed)");
      }
      vtkErrorMacro(<< "No point array named '" << wanted << "' to contour (the input's point "
                    << "arrays: " << (names.empty() ? std::string("none") : names) << ")");
      return 1;
    }
    vtkErrorMacro(<< "No scalars to contour: the input has no point scalars "
                  << "(or no array selected with SetInputArrayToProcess())");
    return 1;
  }
  if (association != vtkDataObject::FIELD_ASSOCIATION_POINTS)
  {
    vtkErrorMacro(<< "Scalars to contour must be point data, not cell or field data");
    return 1;
  }
  if (inScalars->GetNumberOfTuples() != input->GetNumberOfPoints())
  {
    vtkErrorMacro(<< "Scalar array " << (inScalars->GetName() ? inScalars->GetName() : "(unnamed)")
                  << " has " << inScalars->GetNumberOfTuples() << " tuples for "
                  << input->GetNumberOfPoints() << " points");
    return 1;
  }
  const int numComps = inScalars->GetNumberOfComponents();
  if (this->ArrayComponent < 0 || this->ArrayComponent >= numComps)
  {
    vtkErrorMacro(<< "ArrayComponent " << this->ArrayComponent << " is out of range: the array "
                  << (inScalars->GetName() ? inScalars->GetName() : "(unnamed)") << " has "
                  << numComps << " component(s)");
    return 1;
  }
  const int scalarType = vtkPreciseMarchingCubes::LibraryScalarType(inScalars->GetDataType());
  if (scalarType < 0)
  {
    vtkErrorMacro(<< "Unsupported scalar type " << inScalars->GetDataTypeAsString()
                  << ": integer and floating point arrays are supported");
    return 1;
  }

  // The extent contoured: the input's, cropped to the requested update
  // extent. A source may deliver more than it was asked for (ghost layers,
  // or the whole volume from a reader that cannot stream); contouring only
  // the requested piece keeps the pieces of a distributed run from
  // overlapping. Neighbouring pieces share a layer of samples, so their
  // surfaces meet without a gap.
  int dataExtent[6];
  input->GetExtent(dataExtent);
  int dataDims[3];
  input->GetDimensions(dataDims);
  // Ghost arrays that do not fit the image (an upstream filter's fault:
  // VTK 9.1's Extract Subset with a sample rate under MPI) tell nothing of
  // which cells are the piece's own or hidden: read as absent, said.
  for (vtkUnsignedCharArray* flags : { input->GetCellGhostArray(), input->GetPointGhostArray() })
  {
    const bool cells = flags == input->GetCellGhostArray();
    const vtkIdType want = cells ? input->GetNumberOfCells() : input->GetNumberOfPoints();
    if (flags && (flags->GetNumberOfComponents() != 1 || flags->GetNumberOfTuples() != want))
    {
      vtkWarningMacro(<< "The input's " << (cells ? "cell" : "point") << " ghost array holds "
                      << flags->GetNumberOfTuples() << " tuples of "
                      << flags->GetNumberOfComponents() << " component(s) for " << want << " "
                      << (cells ? "cells" : "points")
                      << ": it is ignored, so a distributed piece's ghost layer or blanking "
                         "may be taken for its own cells");
    }
  }
  int extent[6];
  std::copy(dataExtent, dataExtent + 6, extent);
  if (inInfo->Has(vtkStreamingDemandDrivenPipeline::UPDATE_EXTENT()))
  {
    int update[6];
    inInfo->Get(vtkStreamingDemandDrivenPipeline::UPDATE_EXTENT(), update);
    if (update[0] <= update[1] && update[2] <= update[3] && update[4] <= update[5])
    {
      for (int i = 0; i < 3; ++i)
      {
        extent[2 * i] = std::max(extent[2 * i], update[2 * i]);
        extent[2 * i + 1] = std::min(extent[2 * i + 1], update[2 * i + 1]);
      }
    }
  }
  // The cells of the piece (ContourExtent, from RequestUpdateExtent()) are
  // contoured. The cubic filters read one sample more around every cell, a
  // refined cell may depend on the cell across a face, and flat triangles in
  // a face cancel against those of the cell across it
  // (ContourGhostSamples()): the ghost layer the input holds around the piece
  // is contoured too, and the triangles of the ghost cells are dropped below.
  // The prefilter of BSplineInterpolating couples whole lines of samples, so
  // it reads all the input holds (the whole volume, as requested).
  const int ghostSamples =
    ContourGhostSamples(this->ReconstructionFilter, this->Topology, this->Epsilon,
      this->MaxLevel, this->ComputeNormals != 0 || this->ComputeGradients != 0);
  // The samples without which the surface next to a cut differs from the
  // serial one on any data (not only where samples equal the isovalue).
  const int neededSamples =
    GhostSamples(this->ReconstructionFilter, this->Topology, this->Epsilon, this->MaxLevel,
      this->ComputeNormals != 0 || this->ComputeGradients != 0);
  int sampleExtent[6];
  std::copy(extent, extent + 6, sampleExtent);
  if (this->HasContourExtent)
  {
    const bool global = this->ReconstructionFilter == RECONSTRUCTION_BSPLINE_INTERPOLATING;
    int whole[6];
    std::copy(dataExtent, dataExtent + 6, whole);
    if (inInfo->Has(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT()))
    {
      inInfo->Get(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT(), whole);
    }
    int piece[6];
    std::copy(this->ContourExtent, this->ContourExtent + 6, piece);
    if (this->ContourWholeUnknown)
    {
      // No whole extent (RequestUpdateExtent()): the input's extent is
      // taken for the whole volume and the piece cut from it as it would
      // have been. Every piece then holds the volume as delivered: cut as
      // asked by default (a source that ignores pieces gives each the same
      // volume; without the cut the surface came out once per piece);
      // WholeInputShare may say otherwise (ParaView's subclass: a volume
      // on some processes only, or a different one on each).
      std::copy(dataExtent, dataExtent + 6, whole);
      if (this->ContourPieces > 1)
      {
        vtkNew<vtkExtentTranslator> translator;
        if (!translator->PieceToExtentThreadSafe(this->ContourPiece, this->ContourPieces, 0,
              whole, piece, this->ContourSplitMode, 0))
        {
          piece[0] = VTK_INT_MAX;
          piece[1] = VTK_INT_MIN;
        }
      }
      else
      {
        std::copy(whole, whole + 6, piece);
      }
    }
    // A distributed piece's own cells. An input that is the whole volume
    // is, with more pieces asked for, one that every piece holds (ghost
    // array or not: an image with blanked cells, or given with
    // SetInputData): cut as asked, unless WholeInputShare says this piece
    // alone holds it or another one does. Asked for as the only piece, it
    // may be a block of a composite input (the pipeline executes blocks one
    // by one, each a whole volume of its own): cells marked as duplicates
    // are then another piece's ghost layer. Any other input: the cells its
    // ghost array does not mark as duplicates; without one, the piece asked
    // for, unless the input is not that either (split by an upstream filter
    // its own way, as Resample To Image does: then all its cells).
    // (A piece grown by its ghost layer, with the point ghost array only,
    // is the piece asked for when the cells without a duplicate corner are
    // that piece: see OwnCellsByPoints().)
    const bool wholeInput = std::equal(dataExtent, dataExtent + 6, whole);
    auto asAsked = [&](const int e[6]) {
      return SplitAsAsked(
        e, this->ContourPiece, this->ContourPieces, this->ContourSplitExtent, this->ContourSplitMode);
    };
    int byPoints[6];
    const bool ownSplit = wholeInput
      ? this->ContourPieces == 1 && HasDuplicateCells(input)
      : this->ContourPieces > 1 &&
        (input->GetCellGhostArray() != nullptr ||
          !(asAsked(dataExtent) ||
            (OwnCellsByPoints(input, dataExtent, byPoints) && asAsked(byPoints))));
    if (global && wholeInput && ownSplit && this->CompositePieces > 1)
    {
      vtkWarningMacro(<< "A block of a composite input asked for in " << this->CompositePieces
                      << " pieces: the B-Spline Interpolating prefilter reads this block's piece "
                         "and its ghost layer only, not the whole volume, so its surface differs "
                         "from a serial run's throughout (contour the image itself, or one "
                         "piece)");
    }
    int asked[6]; // the piece asked for, before OwnCells() takes the input's own cells
    std::copy(piece, piece + 6, asked);
    if (ownSplit && !OwnCells(input, dataExtent, piece))
    {
      vtkDebugMacro(<< "Every cell of the input piece is a ghost cell");
      return 1;
    }
    if (wholeInput && this->ContourPieces > 1)
    {
      if (this->WholeInputShare == WHOLE_INPUT_NONE)
      {
        vtkDebugMacro(<< "Another piece contours the whole volume");
        return 1;
      }
      if (this->WholeInputShare == WHOLE_INPUT_ALL)
      {
        std::copy(dataExtent, dataExtent + 6, piece);
      }
    }
    if (this->ContourWholeUnknown && this->ContourPieces > 1 &&
      this->WholeInputShare == WHOLE_INPUT_AS_ASKED)
    {
      // Right for a source that delivers the whole volume to every piece
      // (ParaView's Programmable Source without its information script);
      // one that delivers its own piece only loses the rest of the surface
      // here, and nothing tells the two apart: said, not silent.
      vtkWarningMacro(<< "The input reports no whole extent: the volume that arrived ("
                      << dataExtent[0] << ".." << dataExtent[1] << ", " << dataExtent[2] << ".."
                      << dataExtent[3] << ", " << dataExtent[4] << ".." << dataExtent[5]
                      << ") is taken for the whole volume and piece " << this->ContourPiece
                      << " of " << this->ContourPieces << " cut from it is contoured; a source "
                      << "that delivers only its own piece loses the rest of the surface (give "
                      << "the source a whole extent in its RequestInformation, in ParaView the "
                      << "Programmable Source's RequestInformation script)");
    }
    if (IsEmptyExtent(piece))
    {
      // Pieces of a distributed run may be empty; the only piece asked
      // for never is when the input holds cells: not without a word.
      if (this->ContourPieces == 1 && input->GetNumberOfCells() > 0)
      {
        vtkWarningMacro(<< "The extent asked for is empty while the input holds "
                        << input->GetNumberOfCells() << " cells: nothing is contoured");
      }
      vtkDebugMacro(<< "Empty piece");
      return 1;
    }
    for (int i = 0; i < 3; ++i)
    {
      extent[2 * i] = std::max(dataExtent[2 * i], piece[2 * i]);
      extent[2 * i + 1] = std::min(dataExtent[2 * i + 1], piece[2 * i + 1]);
      sampleExtent[2 * i] = global
        ? dataExtent[2 * i]
        : std::max(dataExtent[2 * i], ShiftedIndex(extent[2 * i], -ghostSamples));
      sampleExtent[2 * i + 1] = global
        ? dataExtent[2 * i + 1]
        : std::min(dataExtent[2 * i + 1], ShiftedIndex(extent[2 * i + 1], ghostSamples));
    }
    // Without the samples around the piece that the run needs (see
    // GhostSamples()), the surface next to a cut may differ from the
    // serial one: say so. (Also for an input that is the piece asked for
    // but without the ghost layer asked with it: a source that ignores
    // ghost levels.)
    // (Not for a flat volume: the dimension error below says what is
    // wrong with it, and its pieces, thin along the flat axis, looked a
    // layer short.)
    const bool solid = whole[0] < whole[1] && whole[2] < whole[3] && whole[4] < whole[5];
    bool short_of_samples = false;
    for (int i = 0; solid && (ownSplit || this->ContourPieces > 1) && i < 3; ++i)
    {
      const int want = global ? std::numeric_limits<int>::max() : neededSamples;
      short_of_samples = short_of_samples ||
        (want > 0 && extent[2 * i] > whole[2 * i] &&
          extent[2 * i] - sampleExtent[2 * i] < std::min(want, extent[2 * i] - whole[2 * i])) ||
        (want > 0 && extent[2 * i + 1] < whole[2 * i + 1] &&
          sampleExtent[2 * i + 1] - extent[2 * i + 1] <
            std::min(want, whole[2 * i + 1] - extent[2 * i + 1]));
    }
    if (short_of_samples)
    {
      vtkWarningMacro(<< "The input arrived as the extent (" << dataExtent[0] << ".."
                      << dataExtent[1] << ", " << dataExtent[2] << ".." << dataExtent[3] << ", "
                      << dataExtent[4] << ".." << dataExtent[5] << ") for the piece ("
                      << asked[0] << ".." << asked[1] << ", " << asked[2] << ".." << asked[3]
                      << ", " << asked[4] << ".." << asked[5]
                      << "), without the samples around it that "
                      << (global ? "the B-Spline Interpolating prefilter"
                                 : "normals or gradients, a cubic filter, or refinement on "
                                   "sub-cells")
                      << " read: its own cells are contoured, and next to its faces the "
                         "surface may differ from a serial run's");
    }
  }
  int dims[3];
  int sampleDims[3];
  bool ghostCells = false;
  for (int i = 0; i < 3; ++i)
  {
    dims[i] = extent[2 * i + 1] - extent[2 * i] + 1;
    sampleDims[i] = sampleExtent[2 * i + 1] - sampleExtent[2 * i] + 1;
    ghostCells = ghostCells || sampleExtent[2 * i] != extent[2 * i] ||
      sampleExtent[2 * i + 1] != extent[2 * i + 1];
  }
  // Cells the input's ghost arrays hide (blanking: in AMR data, a finer
  // block covers them) make no triangles, as vtkContourFilter skips them
  // in a vtkUniformGrid; their samples still shape the surface around. A
  // cell is hidden when its cell flag says HIDDENCELL or a corner's point
  // flag says HIDDENPOINT (vtkUniformGrid::IsCellVisible()).
  const unsigned char* hidden = nullptr;
  vtkIdType cellDims[3];
  vtkIdType cells = 1;
  for (int i = 0; i < 3; ++i)
  {
    cellDims[i] =
      std::max<vtkIdType>(0, static_cast<vtkIdType>(dataExtent[2 * i + 1]) - dataExtent[2 * i]);
    cells *= cellDims[i];
  }
  if (vtkUnsignedCharArray* flags = input->GetCellGhostArray())
  {
    const unsigned char* flag = flags->GetPointer(0);
    if (flags->GetNumberOfComponents() == 1 && flags->GetNumberOfTuples() == cells &&
      std::any_of(flag, flag + cells,
        [](unsigned char f) { return (f & vtkDataSetAttributes::HIDDENCELL) != 0; }))
    {
      hidden = flag;
    }
  }
  std::vector<unsigned char> hiddenByPoints;
  if (vtkUnsignedCharArray* flags = input->GetPointGhostArray())
  {
    const vtkIdType pdims[3] = { cellDims[0] + 1, cellDims[1] + 1, cellDims[2] + 1 };
    const unsigned char* flag = flags->GetPointer(0);
    const vtkIdType points = pdims[0] * pdims[1] * pdims[2];
    if (cells > 0 && flags->GetNumberOfComponents() == 1 && flags->GetNumberOfTuples() == points &&
      std::any_of(flag, flag + points,
        [](unsigned char f) { return (f & vtkDataSetAttributes::HIDDENPOINT) != 0; }))
    {
      if (hidden)
      {
        hiddenByPoints.assign(hidden, hidden + cells);
      }
      else
      {
        hiddenByPoints.assign(static_cast<size_t>(cells), 0);
      }
      auto off = [&](vtkIdType i, vtkIdType j, vtkIdType k) {
        return (flag[i + pdims[0] * (j + pdims[1] * k)] & vtkDataSetAttributes::HIDDENPOINT) != 0;
      };
      vtkIdType c = 0;
      for (vtkIdType k = 0; k < cellDims[2]; ++k)
      {
        for (vtkIdType j = 0; j < cellDims[1]; ++j)
        {
          for (vtkIdType i = 0; i < cellDims[0]; ++i, ++c)
          {
            if (off(i, j, k) || off(i + 1, j, k) || off(i, j + 1, k) || off(i + 1, j + 1, k) ||
              off(i, j, k + 1) || off(i + 1, j, k + 1) || off(i, j + 1, k + 1) ||
              off(i + 1, j + 1, k + 1))
            {
              hiddenByPoints[static_cast<size_t>(c)] |= vtkDataSetAttributes::HIDDENCELL;
            }
          }
        }
      }
      hidden = hiddenByPoints.data();
    }
  }
  const bool selectCells = ghostCells || hidden != nullptr;
  if (dims[0] < 1 || dims[1] < 1 || dims[2] < 1)
  {
    if ((!this->HasContourExtent || this->ContourPieces == 1) && input->GetNumberOfCells() > 0)
    {
      vtkWarningMacro(<< "The extent asked for holds none of the input's "
                      << input->GetNumberOfCells() << " cells: nothing is contoured");
    }
    vtkDebugMacro(<< "The requested extent holds no samples of the input");
    return 1;
  }
  if (dims[0] < 2 || dims[1] < 2 || dims[2] < 2)
  {
    // A 2D volume is an error. A piece of a 3D volume that is a single
    // layer of samples (vtkExtentTranslator makes such pieces when it cuts
    // an axis into more parts than it has cells, as 3 pieces of a volume
    // two cells wide) holds no cell: it has no surface, like an empty piece.
    int whole[6];
    std::copy(dataExtent, dataExtent + 6, whole);
    if (inInfo->Has(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT()))
    {
      inInfo->Get(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT(), whole);
    }
    if (whole[0] < whole[1] && whole[2] < whole[3] && whole[4] < whole[5])
    {
      vtkDebugMacro(<< "The piece holds no cells of the volume (dimensions " << dims[0] << " x "
                    << dims[1] << " x " << dims[2] << ")");
      return 1;
    }
    vtkErrorMacro(<< "Cannot contour data of dimension != 3 (dimensions " << dims[0] << " x "
                  << dims[1] << " x " << dims[2] << ")");
    return 1;
  }

  // The samples are read in place; only arrays without the standard
  // (array-of-structures) memory layout are copied first.
  vtkSmartPointer<vtkDataArray> contiguous = inScalars;
  if (!inScalars->HasStandardMemoryLayout())
  {
    contiguous = vtkSmartPointer<vtkDataArray>::Take(
      vtkDataArray::CreateDataArray(inScalars->GetDataType()));
    contiguous->DeepCopy(inScalars);
  }

  // Geometry: the library works on an axis-aligned grid. With the identity
  // direction and positive spacing it produces world coordinates directly;
  // otherwise points are mapped from index space with the image's
  // IndexToPhysical matrix afterwards (and normals and gradients with its
  // inverse transpose).
  const double* origin = input->GetOrigin();
  const double* spacing = input->GetSpacing();
  vtkMatrix3x3* direction = input->GetDirectionMatrix();
  bool axisAligned = direction->IsIdentity() && spacing[0] > 0.0 && spacing[1] > 0.0 &&
    spacing[2] > 0.0;
  for (int i = 0; i < 3; ++i)
  {
    if (!(spacing[i] != 0.0) || !std::isfinite(spacing[i]) || !std::isfinite(origin[i]))
    {
      vtkErrorMacro(<< "Invalid image geometry: spacing (" << spacing[0] << ", " << spacing[1]
                    << ", " << spacing[2] << "), origin (" << origin[0] << ", " << origin[1]
                    << ", " << origin[2] << ")");
      return 1;
    }
  }

  // Index space -> world for the general case: x = origin + D * S * ijk
  // (checked before any work: a singular matrix is an error).
  double indexToWorld[3][3];
  double normalMatrix[3][3];
  bool flipWinding = false;
  if (!axisAligned)
  {
    double scaled[3][3];
    for (int r = 0; r < 3; ++r)
    {
      for (int c = 0; c < 3; ++c)
      {
        if (!std::isfinite(direction->GetElement(r, c)))
        {
          vtkErrorMacro(<< "The direction matrix of the input has a NaN or infinite entry");
          output->Initialize();
          return 1;
        }
      }
    }
    for (int r = 0; r < 3; ++r)
    {
      for (int c = 0; c < 3; ++c)
      {
        indexToWorld[r][c] = direction->GetElement(r, c) * spacing[c];
        // The library's normals and gradients are in the axis-aligned frame
        // with |spacing|: map them with the inverse transpose of D * sign(S)
        // (a gradient is a covector: for x = origin + D * S * ijk, the
        // world gradient is (D S)^-T times the index one, which is
        // (D sign(S))^-T times the library's, the index one over |S|).
        scaled[r][c] = direction->GetElement(r, c) * (spacing[c] < 0.0 ? -1.0 : 1.0);
      }
    }
    if (!InverseTranspose(scaled, normalMatrix))
    {
      // (A matrix scaled by 1e-300 or 1e300 is invertible, but its
      // determinant under- or overflows: said so, not called singular.)
      vtkErrorMacro(<< "The direction matrix of the input is singular, or its determinant "
                       "under- or overflows double precision (a direction matrix turns or "
                       "mirrors: its columns have unit length)");
      output->Initialize();
      return 1;
    }
    // A mirroring transform would turn the triangles inside out: keep the
    // normal (p1 - p0) x (p2 - p0) pointing towards lower values.
    flipWinding = vtkMath::Determinant3x3(indexToWorld) < 0.0;
  }

  // The world box of the extent. Points are mapped below as origin +
  // column 0 * i + column 1 * j + column 2 * k: each partial sum is linear
  // in the indices, so when it is finite at the corners of the extent it
  // is finite everywhere in it. (The library refuses an overflowing
  // axis-aligned grid itself.) Its largest coordinate decides whether
  // float points can hold the output: that of the whole volume's extent
  // where the pipeline gives one, so that every piece of a distributed run
  // decides as a serial run does (a piece nearer the origin took float
  // points, its neighbour double ones, and they no longer met).
  int boxExtent[6];
  std::copy(dataExtent, dataExtent + 6, boxExtent);
  if (inInfo->Has(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT()))
  {
    int whole[6];
    inInfo->Get(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT(), whole);
    if (!IsEmptyExtent(whole))
    {
      for (int i = 0; i < 3; ++i)
      {
        boxExtent[2 * i] = std::min(boxExtent[2 * i], whole[2 * i]);
        boxExtent[2 * i + 1] = std::max(boxExtent[2 * i + 1], whole[2 * i + 1]);
      }
    }
  }
  double worldMax = 0.0;
  double largest[3] = { 0.0, 0.0, 0.0 }; // per world axis
  for (int corner = 0; corner < 8; ++corner)
  {
    const double ijk[3] = { static_cast<double>(boxExtent[corner & 1 ? 1 : 0]),
      static_cast<double>(boxExtent[corner & 2 ? 3 : 2]),
      static_cast<double>(boxExtent[corner & 4 ? 5 : 4]) };
    for (int r = 0; r < 3; ++r)
    {
      double x = origin[r];
      bool finite = true;
      for (int c = 0; c < 3; ++c)
      {
        x += (axisAligned ? (r == c ? spacing[c] : 0.0) : indexToWorld[r][c]) * ijk[c];
        finite = finite && std::isfinite(x);
      }
      if (!finite && !axisAligned)
      {
        vtkErrorMacro(<< "Invalid image geometry: the world coordinates of the extent ("
                      << boxExtent[0] << ".." << boxExtent[1] << ", " << boxExtent[2] << ".."
                      << boxExtent[3] << ", " << boxExtent[4] << ".." << boxExtent[5]
                      << ") are not finite (they overflow) with origin (" << origin[0] << ", "
                      << origin[1] << ", " << origin[2] << "), spacing (" << spacing[0] << ", "
                      << spacing[1] << ", " << spacing[2] << ") and the direction matrix");
        output->Initialize();
        return 1;
      }
      if (finite)
      {
        worldMax = std::max(worldMax, std::fabs(x));
        largest[r] = std::max(largest[r], std::fabs(x));
      }
    }
  }
  // Float points would be infinite beyond float's range: DEFAULT_PRECISION
  // then gives double points, SINGLE_PRECISION is refused.
  const bool floatOverflows = worldMax > static_cast<double>(std::numeric_limits<float>::max());
  if (floatOverflows && this->OutputPointsPrecision == vtkAlgorithm::SINGLE_PRECISION)
  {
    vtkErrorMacro(<< "The world coordinates of the input reach " << worldMax
                  << ", beyond single precision: set OutputPointsPrecision to DOUBLE_PRECISION "
                     "(or DEFAULT_PRECISION; in ParaView, Output Points Precision to Double or "
                     "Default)");
    output->Initialize();
    return 1;
  }
  // Float points can also be too coarse: a cell whose side is below
  // float's least normal number (a spacing of 1e-200), or spans fewer
  // float steps at the largest coordinate than refinement's finest level
  // divides it into (an origin of 1e7 with unit spacing), puts distinct
  // points on one float. DEFAULT_PRECISION then gives double points too;
  // SINGLE_PRECISION warns.
  double smallestCell = std::numeric_limits<double>::infinity();
  for (int c = 0; c < 3; ++c)
  {
    double side = std::fabs(spacing[c]);
    if (!axisAligned)
    {
      side = std::sqrt(indexToWorld[0][c] * indexToWorld[0][c] +
        indexToWorld[1][c] * indexToWorld[1][c] + indexToWorld[2][c] * indexToWorld[2][c]);
    }
    smallestCell = std::min(smallestCell, side);
  }
  const double floatStep = worldMax * std::ldexp(1.0, -23); // float's spacing near worldMax
  const bool floatBlurs = smallestCell < static_cast<double>(std::numeric_limits<float>::min()) ||
    smallestCell < floatStep * std::ldexp(1.0, std::max(0, this->MaxLevel));
  // Double points can be too coarse as well. A world coordinate x is held
  // to half an ulp, |x| 2^-53, which moves a point along index axis c by
  // sum over r of |D^-1[c][r]| |x_r| 2^-53 / |spacing c| cells: with a
  // spacing below 2^-40 times that reach (an origin of 1e17 with unit
  // spacing) every point is rounded by more than 1e-4 of a cell, and from
  // 2^-52 down a cell's points fall onto each other. No precision gives
  // better points there (the command-line tool refuses such a volume as it
  // reads it, with the same bound): said, not silent.
  int blurredAxis = -1;
  double blurredReach = 0.0;
  for (int c = 0; c < 3 && blurredAxis < 0; ++c)
  {
    double reach = axisAligned ? largest[c] : 0.0;
    if (!axisAligned)
    {
      // normalMatrix is (D sign(S))^-T: its entry [r][c] is D^-1[c][r]
      // up to sign.
      for (int r = 0; r < 3; ++r)
      {
        reach += std::fabs(normalMatrix[r][c]) * largest[r];
      }
    }
    if (std::fabs(spacing[c]) < std::ldexp(reach, -40))
    {
      blurredAxis = c;
      blurredReach = reach;
    }
  }
  if (blurredAxis >= 0)
  {
    vtkWarningMacro(<< "The input's world coordinates (up to " << blurredReach
                    << " along index axis " << blurredAxis << ") are too large for its spacing ("
                    << std::fabs(spacing[blurredAxis])
                    << "): even double-precision points are rounded by more than 1e-4 of a cell "
                       "there, and distinct points may coincide; move the image's origin nearer "
                       "to its extent");
  }
  else if (floatBlurs && !floatOverflows &&
    this->OutputPointsPrecision == vtkAlgorithm::SINGLE_PRECISION)
  {
    vtkWarningMacro(<< "Single-precision points cannot tell this input's cells apart (a cell "
                    << smallestCell << " wide at coordinates up to " << worldMax
                    << "): distinct points will coincide; set OutputPointsPrecision to "
                       "DOUBLE_PRECISION or DEFAULT_PRECISION");
  }
  const bool doublePoints = this->OutputPointsPrecision == vtkAlgorithm::DOUBLE_PRECISION ||
    floatOverflows ||
    (floatBlurs && this->OutputPointsPrecision == vtkAlgorithm::DEFAULT_PRECISION);

  // The first sample read (of the contoured extent, or of its ghost layer),
  // as a value index.
  const uint64_t first = static_cast<uint64_t>(numComps) *
      (static_cast<uint64_t>(sampleExtent[0] - dataExtent[0]) +
        static_cast<uint64_t>(sampleExtent[2] - dataExtent[2]) *
          static_cast<uint64_t>(dataDims[0]) +
        static_cast<uint64_t>(sampleExtent[4] - dataExtent[4]) *
          static_cast<uint64_t>(dataDims[0]) * static_cast<uint64_t>(dataDims[1])) +
    static_cast<uint64_t>(this->ArrayComponent);
  pmc_volume volume = pmc_volume(); // zeroed, then struct_size first
  volume.struct_size = sizeof(volume);
  volume.data = static_cast<const char*>(contiguous->GetVoidPointer(0)) +
    static_cast<size_t>(first) * contiguous->GetDataTypeSize();
  volume.len = static_cast<uint64_t>(contiguous->GetNumberOfValues()) - first;
  volume.scalar_type = static_cast<pmc_scalar_type>(scalarType);
  for (int i = 0; i < 3; ++i)
  {
    volume.dims[i] = static_cast<uint64_t>(sampleDims[i]);
    volume.origin[i] = axisAligned ? origin[i] : 0.0;
    volume.spacing[i] = std::fabs(spacing[i]);
  }
  volume.strides[0] = numComps;
  volume.strides[1] = static_cast<int64_t>(numComps) * dataDims[0];
  volume.strides[2] = static_cast<int64_t>(numComps) * dataDims[0] * dataDims[1];

  // Options shared by all contour values.
  OptionsPtr options(pmc_options_new());
  if (!options)
  {
    vtkErrorMacro(<< "Cannot create PreciseMC options: " << LastError(PMC_STATUS_OUT_OF_MEMORY));
    return 1;
  }
  bool computeNormals = this->ComputeNormals != 0;
  bool computeGradients = this->ComputeGradients != 0;
  // The library makes gradients as it makes normals, the exact ones when
  // normals are off: central-difference gradients without normals need
  // them asked for too (and dropped).
  const bool libraryNormals = computeNormals ||
    (computeGradients && this->NormalMode == NORMALS_CENTRAL_DIFFERENCE);
  const int64_t indexOffset[3] = { sampleExtent[0], sampleExtent[2], sampleExtent[4] };
  ProgressState progress = { this, 0.0, 1.0, nullptr };
  pmc_status status = PMC_STATUS_OK;
  const char* failed = nullptr;
  if ((status = pmc_options_set_epsilon(options.get(), this->Epsilon)) != PMC_STATUS_OK)
  {
    failed = "Epsilon";
  }
  else if ((status = pmc_options_set_max_level(
              options.get(), static_cast<uint32_t>(this->MaxLevel))) != PMC_STATUS_OK)
  {
    failed = "MaxLevel";
  }
  else if ((status = pmc_options_set_rule(options.get(), static_cast<pmc_rule>(this->Rule))) !=
    PMC_STATUS_OK)
  {
    failed = "Rule";
  }
  else if ((status = pmc_options_set_reconstruction(options.get(),
              static_cast<pmc_reconstruction>(this->ReconstructionFilter))) != PMC_STATUS_OK)
  {
    failed = "ReconstructionFilter";
  }
  else if ((status = pmc_options_set_topology(
              options.get(), static_cast<pmc_topology>(this->Topology))) != PMC_STATUS_OK)
  {
    failed = "Topology";
  }
  else if ((status = pmc_options_set_normals(options.get(),
              libraryNormals ? static_cast<pmc_normals>(this->NormalMode)
                             : static_cast<pmc_normals>(PMC_NORMALS_NONE))) != PMC_STATUS_OK)
  {
    failed = "NormalMode";
  }
  else if ((status = pmc_options_set_gradients(options.get(), computeGradients ? 1 : 0)) !=
    PMC_STATUS_OK)
  {
    failed = "ComputeGradients";
  }
  else if ((status = pmc_options_set_max_triangles(options.get(), this->MaxTriangles)) !=
    PMC_STATUS_OK)
  {
    failed = "MaxTriangles";
  }
  else if ((status = pmc_options_set_threads(
              options.get(), static_cast<uint32_t>(this->NumberOfThreads))) != PMC_STATUS_OK)
  {
    failed = "NumberOfThreads";
  }
  else if (this->UseSMPTools &&
    (status = pmc_options_set_executor(options.get(), &SMPExecutor, nullptr,
       static_cast<uint32_t>(std::min<int>(std::max(1, vtkSMPTools::GetEstimatedNumberOfThreads()),
         static_cast<int>(PMC_MAX_THREADS))))) !=
      PMC_STATUS_OK)
  {
    failed = "UseSMPTools";
  }
  else if ((status = pmc_options_set_index_offset(options.get(), indexOffset)) != PMC_STATUS_OK)
  {
    failed = "index offset";
  }
  else if ((status = pmc_options_set_progress(options.get(), &ProgressCallback, &progress)) !=
    PMC_STATUS_OK)
  {
    failed = "progress callback";
  }
  if (failed)
  {
    vtkErrorMacro(<< "Invalid " << failed << ": " << LastError(status));
    return 1;
  }

  // Extract each contour value in turn.
  ++this->NumberOfExecutions;
  std::vector<MeshPtr> meshes;
  meshes.reserve(static_cast<size_t>(numContours));
  std::vector<MeshSelection> selections(static_cast<size_t>(numContours));
  vtkTypeUInt64 totalPoints = 0;
  vtkTypeUInt64 totalTriangles = 0;
  double levelSum = 0.0;
  auto start = std::chrono::steady_clock::now();
  this->UpdateProgress(0.0);
  // One extraction of `value` with the options as they stand: the mesh,
  // its statistics and, with a ghost layer or hidden cells, the triangles
  // kept. False when it failed (said) or was aborted: the output is then
  // empty and the run ends. An observer's exception is thrown on.
  const auto extractOnce = [&](double value, MeshPtr& mesh, pmc_stats& stats,
                             MeshSelection& selection) -> bool {
    pmc_mesh* raw = nullptr;
    status = pmc_extract(&volume, value, options.get(), &raw);
    mesh.reset(raw);
    if (progress.Thrown)
    {
      // Reported by RequestData().
      std::rethrow_exception(progress.Thrown);
    }
    const char* why = nullptr;
    if (status == PMC_STATUS_ABORTED || (status != PMC_STATUS_OK && this->GetAbortExecute()))
    {
      vtkDebugMacro(<< "Aborted");
    }
    else if (status != PMC_STATUS_OK || !mesh)
    {
      why = "PreciseMC extraction failed for contour value ";
    }
    else
    {
      stats = pmc_stats();
      stats.struct_size = sizeof(stats);
      if ((status = pmc_mesh_stats(mesh.get(), &stats)) != PMC_STATUS_OK)
      {
        why = "Cannot read PreciseMC statistics for contour value ";
      }
      else if (!selectCells)
      {
        selection.NumberOfPoints = pmc_mesh_point_count(mesh.get());
        selection.NumberOfTriangles = pmc_mesh_triangle_count(mesh.get());
        return true;
      }
      else if ((pmc_mesh_point_count(mesh.get()) > 0 && !pmc_mesh_index_points(mesh.get())) ||
        (pmc_mesh_triangle_count(mesh.get()) > 0 &&
          (!pmc_mesh_triangles(mesh.get()) || !pmc_mesh_triangle_levels(mesh.get()))))
      {
        status = PMC_STATUS_OK;
        why = "PreciseMC returned an incomplete mesh for contour value ";
      }
      else
      {
        SelectCells(mesh.get(), extent, sampleExtent, hidden, dataExtent, selection);
        return true;
      }
    }
    if (why)
    {
      vtkErrorMacro(<< why << value
                    << (status != PMC_STATUS_OK ? ": " + LastError(status) : std::string()));
    }
    this->ResetStatistics();
    output->Initialize();
    return false;
  };
  for (vtkIdType c = 0; c < numContours; ++c)
  {
    progress.Base = static_cast<double>(c) / numContours;
    progress.Span = 1.0 / numContours;
    MeshPtr mesh;
    pmc_stats stats = pmc_stats();
    MeshSelection& selection = selections[static_cast<size_t>(c)];
    if (!extractOnce(values[c], mesh, stats, selection))
    {
      return 1;
    }
    // MaxTriangles caps the output, but the library's cap counted the
    // triangles of the ghost layer and of hidden cells too, which were
    // dropped: a higher level may fit. The levels above are tried in turn
    // while the triangles kept fit, the library's cap raised by the share
    // dropped at the last level that fitted, and a quarter more (a guard on
    // time and memory: a level the library must stop short of is not
    // tried).
    if (selectCells && stats.budget_reached && selection.NumberOfTriangles > 0 &&
      selection.NumberOfTriangles < pmc_mesh_triangle_count(mesh.get()))
    {
      uint32_t level = stats.effective_max_level;
      progress.Span = 0.0; // the bar stays where it is
      while (level < static_cast<uint32_t>(this->MaxLevel))
      {
        const double share = static_cast<double>(pmc_mesh_triangle_count(mesh.get())) /
          static_cast<double>(std::max<vtkTypeUInt64>(selection.NumberOfTriangles, 1));
        const double guard = std::min(1.25 * share * static_cast<double>(this->MaxTriangles),
          std::ldexp(1.0, 62));
        if (pmc_options_set_max_level(options.get(), level + 1) != PMC_STATUS_OK ||
          pmc_options_set_max_triangles(options.get(), static_cast<uint64_t>(guard)) !=
            PMC_STATUS_OK)
        {
          break;
        }
        MeshPtr higher;
        pmc_stats higherStats = pmc_stats();
        MeshSelection higherSelection;
        if (!extractOnce(values[c], higher, higherStats, higherSelection))
        {
          return 1;
        }
        if (higherStats.effective_max_level != level + 1 ||
          higherSelection.NumberOfTriangles > this->MaxTriangles)
        {
          break;
        }
        mesh = std::move(higher);
        stats = higherStats;
        selection = std::move(higherSelection);
        ++level;
      }
      stats.budget_reached = level < static_cast<uint32_t>(this->MaxLevel);
      if ((status = pmc_options_set_max_level(
             options.get(), static_cast<uint32_t>(this->MaxLevel))) != PMC_STATUS_OK ||
        (status = pmc_options_set_max_triangles(options.get(), this->MaxTriangles)) !=
          PMC_STATUS_OK)
      {
        vtkErrorMacro(<< "Cannot restore MaxLevel and MaxTriangles: " << LastError(status));
        this->ResetStatistics();
        output->Initialize();
        return 1;
      }
    }
    if (selectCells)
    {
      // The output statistics describe the kept triangles only.
      const uint8_t* triLevels = pmc_mesh_triangle_levels(mesh.get());
      for (vtkIdType t : selection.Triangles)
      {
        this->MaxLevelReached = std::max(this->MaxLevelReached, static_cast<int>(triLevels[t]));
        levelSum += triLevels[t];
      }
    }
    else
    {
      this->MaxLevelReached = std::max(this->MaxLevelReached, static_cast<int>(stats.max_level));
      levelSum += stats.mean_level * static_cast<double>(stats.output_triangles);
    }
    this->NumberOfMCTriangles += stats.mc_triangles;
    this->NumberOfRefinedTriangles +=
      selectCells ? selection.NumberOfTriangles : stats.output_triangles;
    this->NumberOfAmbiguousCells += stats.ambiguous_cells;
    this->NumberOfSkippedCells += stats.skipped_nonfinite_cells;
    this->NumberOfSamplesEvaluated += stats.samples_evaluated;
    this->NumberOfSplitPoints += stats.split_points;
    this->NumberOfProjectionFailures += stats.projection_failures;
    this->NumberOfFacesAboveEpsilon += stats.faces_above_epsilon;
    this->NumberOfCellsRefinedOnFacesOnly += pmc_mesh_cells_refined_on_faces_only(mesh.get());
    this->NumberOfRecutPolygons += pmc_mesh_recut_polygons(mesh.get());
    this->NumberOfCellsOnSubcells += pmc_mesh_cells_on_subcells(mesh.get());
    this->BudgetReached = this->BudgetReached || stats.budget_reached;
    totalPoints += selection.NumberOfPoints;
    totalTriangles += selection.NumberOfTriangles;
    meshes.push_back(std::move(mesh));
  }
  this->MeanLevel = totalTriangles > 0 ? levelSum / static_cast<double>(totalTriangles) : 0.0;
  if (this->BudgetReached && inInfo->Has(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT()))
  {
    // Each piece meets the cap on its own, at the level that fits it: two
    // pieces at different levels do not meet along their cut.
    int whole[6];
    inInfo->Get(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT(), whole);
    if (!std::equal(extent, extent + 6, whole))
    {
      vtkWarningMacro(<< "MaxTriangles (" << this->MaxTriangles
                      << ") lowered the refinement level of this piece of the volume: the "
                         "pieces' surfaces may not meet along their cuts (raise MaxTriangles, "
                         "or contour the volume in one piece)");
    }
  }
  this->ExecutionTime =
    std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (totalPoints > static_cast<vtkTypeUInt64>(VTK_ID_MAX / 4) ||
    totalTriangles > static_cast<vtkTypeUInt64>(VTK_ID_MAX / 4))
  {
    vtkErrorMacro(<< "Output too large for vtkIdType: " << totalPoints << " points, "
                  << totalTriangles << " triangles");
    this->ResetStatistics();
    output->Initialize();
    return 1;
  }
  const vtkIdType numPts = static_cast<vtkIdType>(totalPoints);
  const vtkIdType numTris = static_cast<vtkIdType>(totalTriangles);

  // Points.
  vtkNew<vtkPoints> newPts;
  newPts->SetDataType(doublePoints ? VTK_DOUBLE : VTK_FLOAT);
  newPts->SetNumberOfPoints(numPts);
  RequireLength(newPts->GetNumberOfPoints(), numPts);
  float* floatPts = nullptr;
  double* doublePts = nullptr;
  if (newPts->GetDataType() == VTK_FLOAT)
  {
    floatPts = vtkFloatArray::SafeDownCast(newPts->GetData())->GetPointer(0);
  }
  else
  {
    doublePts = vtkDoubleArray::SafeDownCast(newPts->GetData())->GetPointer(0);
  }
  vtkSmartPointer<vtkFloatArray> newNormals;
  if (computeNormals)
  {
    newNormals = vtkSmartPointer<vtkFloatArray>::New();
    newNormals->SetName("Normals");
    newNormals->SetNumberOfComponents(3);
    newNormals->SetNumberOfTuples(numPts);
    RequireLength(newNormals->GetNumberOfTuples(), numPts);
  }
  vtkSmartPointer<vtkFloatArray> newGradients;
  if (computeGradients)
  {
    newGradients = vtkSmartPointer<vtkFloatArray>::New();
    newGradients->SetName("Gradients");
    newGradients->SetNumberOfComponents(3);
    newGradients->SetNumberOfTuples(numPts);
    RequireLength(newGradients->GetNumberOfTuples(), numPts);
  }
  vtkSmartPointer<vtkDataArray> newScalars;
  if (this->ComputeScalars)
  {
    newScalars = vtkSmartPointer<vtkDataArray>::Take(inScalars->NewInstance());
    newScalars->SetName(inScalars->GetName());
    newScalars->SetNumberOfComponents(1);
    newScalars->SetNumberOfTuples(numPts);
    RequireLength(newScalars->GetNumberOfTuples(), numPts);
  }
  // The connectivity: one contour, kept whole and in the library's winding,
  // is the library's own triangle array, adopted without a copy (it is
  // freed by pmc_buffer_free when VTK lets it go); otherwise a copy.
  vtkNew<vtkIdTypeArray> connectivity;
  bool adopted = false;
  if (numContours == 1 && selections[0].All && !flipWinding && numTris > 0 &&
    sizeof(vtkIdType) == sizeof(int64_t))
  {
    uint64_t count = 0;
    int64_t* taken = pmc_mesh_take_triangles(meshes[0].get(), &count);
    if (!taken || count != static_cast<uint64_t>(numTris))
    {
      pmc_buffer_free(taken);
      vtkErrorMacro(<< "PreciseMC returned an incomplete mesh for contour value " << values[0]);
      this->ResetStatistics();
      output->Initialize();
      return 1;
    }
    connectivity->SetArray(reinterpret_cast<vtkIdType*>(taken), 3 * numTris, /*save=*/0,
      vtkAbstractArray::VTK_DATA_ARRAY_USER_DEFINED);
    connectivity->SetArrayFreeFunction(pmc_buffer_free);
    adopted = true;
  }
  else
  {
    connectivity->SetNumberOfValues(3 * numTris);
    RequireLength(connectivity->GetNumberOfValues(), 3 * numTris);
  }
  vtkNew<vtkIdTypeArray> offsets;
  offsets->SetNumberOfValues(numTris + 1);
  RequireLength(offsets->GetNumberOfValues(), numTris + 1);
  vtkSmartPointer<vtkUnsignedCharArray> levels;
  if (this->ComputeLevels)
  {
    levels = vtkSmartPointer<vtkUnsignedCharArray>::New();
    levels->SetName("RefinementLevel");
    levels->SetNumberOfTuples(numTris);
    RequireLength(levels->GetNumberOfTuples(), numTris);
  }
  // Global index coordinates of all output points, for InterpolateAttributes.
  std::vector<double> indexPoints;
  if (this->InterpolateAttributes)
  {
    indexPoints.resize(3 * static_cast<size_t>(numPts));
  }

  // The copies below write disjoint ranges of preallocated arrays: for a
  // large output, with more than one thread allowed, they run through
  // vtkSMPTools (whose backend and thread count the application chooses).
  auto forRange = [this](vtkIdType n, const std::function<void(vtkIdType, vtkIdType)>& f) {
    if ((this->NumberOfThreads == 1 && !this->UseSMPTools) || n < 65536)
    {
      f(0, n);
    }
    else
    {
      vtkSMPTools::For(0, n, f);
    }
  };
  vtkIdType ptOffset = 0;
  vtkIdType triOffset = 0;
  vtkIdType* conn = connectivity->GetPointer(0);
  vtkIdType* offs = offsets->GetPointer(0);
  if (!adopted)
  {
    AdviseHugePages(conn, sizeof(vtkIdType) * 3 * static_cast<size_t>(numTris));
  }
  AdviseHugePages(offs, sizeof(vtkIdType) * static_cast<size_t>(numTris + 1));
  AdviseHugePages(newPts->GetVoidPointer(0),
    static_cast<size_t>(newPts->GetData()->GetDataTypeSize()) * 3 * static_cast<size_t>(numPts));
  if (newNormals)
  {
    AdviseHugePages(newNormals->GetPointer(0), sizeof(float) * 3 * static_cast<size_t>(numPts));
  }
  if (newGradients)
  {
    AdviseHugePages(
      newGradients->GetPointer(0), sizeof(float) * 3 * static_cast<size_t>(numPts));
  }
  for (vtkIdType c = 0; c < numContours; ++c)
  {
    const pmc_mesh* mesh = meshes[c].get();
    const vtkIdType np = static_cast<vtkIdType>(pmc_mesh_point_count(mesh));
    const vtkIdType nt = static_cast<vtkIdType>(pmc_mesh_triangle_count(mesh));
    // World points are mapped here from the index points (the library
    // computes its own only on request): the same origin + spacing * ijk.
    const double* ijk = pmc_mesh_index_points(mesh);
    const int64_t* tris = pmc_mesh_triangles(mesh);
    const float* normals = pmc_mesh_normals(mesh);
    const float* gradients = pmc_mesh_gradients(mesh);
    const uint8_t* triLevels = pmc_mesh_triangle_levels(mesh);
    if ((np > 0 && !ijk) || (nt > 0 && (!tris || !triLevels)) ||
      (adopted && static_cast<vtkIdType>(selections[0].NumberOfTriangles) > 0 && !triLevels) ||
      (computeNormals && np > 0 && !normals) || (computeGradients && np > 0 && !gradients))
    {
      vtkErrorMacro(<< "PreciseMC returned an incomplete mesh for contour value " << values[c]);
      this->ResetStatistics();
      output->Initialize();
      return 1;
    }
    // Output index of point i (all points, or those of the kept triangles).
    const MeshSelection& selection = selections[static_cast<size_t>(c)];
    const vtkIdType* pointMap = selection.All ? nullptr : selection.PointMap.data();

    // Float points of an axis-aligned image, nothing else per point: the
    // common case, in a loop without per-point branches (the general one
    // below cost about as much as copying every array twice).
    const bool plainPoints =
      !pointMap && axisAligned && floatPts && !computeNormals && !computeGradients &&
      indexPoints.empty();
    forRange(np, [&](vtkIdType first, vtkIdType last) {
      if (plainPoints)
      {
        const double o0 = volume.origin[0], o1 = volume.origin[1], o2 = volume.origin[2];
        const double s0 = volume.spacing[0], s1 = volume.spacing[1], s2 = volume.spacing[2];
        const double* p = ijk + 3 * first;
        float* out = floatPts + 3 * (ptOffset + first);
        for (vtkIdType i = first; i < last; ++i, p += 3, out += 3)
        {
          out[0] = static_cast<float>(o0 + s0 * p[0]);
          out[1] = static_cast<float>(o1 + s1 * p[1]);
          out[2] = static_cast<float>(o2 + s2 * p[2]);
        }
        return;
      }
      for (vtkIdType i = first; i < last; ++i)
      {
        if (pointMap && pointMap[i] < 0)
        {
          continue;
        }
        const vtkIdType o = ptOffset + (pointMap ? pointMap[i] : i);
        double x[3];
        const double* p = ijk + 3 * i;
        if (axisAligned)
        {
          for (int r = 0; r < 3; ++r)
          {
            x[r] = volume.origin[r] + volume.spacing[r] * p[r];
          }
        }
        else
        {
          for (int r = 0; r < 3; ++r)
          {
            x[r] = origin[r] + indexToWorld[r][0] * p[0] + indexToWorld[r][1] * p[1] +
              indexToWorld[r][2] * p[2];
          }
        }
        if (floatPts)
        {
          for (int r = 0; r < 3; ++r)
          {
            floatPts[3 * o + r] = static_cast<float>(x[r]);
          }
        }
        else
        {
          std::copy(x, x + 3, doublePts + 3 * o);
        }
        if (computeNormals)
        {
          float* n = newNormals->GetPointer(3 * o);
          const float* m = normals + 3 * i;
          if (axisAligned)
          {
            n[0] = m[0];
            n[1] = m[1];
            n[2] = m[2];
          }
          else
          {
            double v[3];
            for (int r = 0; r < 3; ++r)
            {
              v[r] =
                normalMatrix[r][0] * m[0] + normalMatrix[r][1] * m[1] + normalMatrix[r][2] * m[2];
            }
            vtkMath::Normalize(v);
            n[0] = static_cast<float>(v[0]);
            n[1] = static_cast<float>(v[1]);
            n[2] = static_cast<float>(v[2]);
          }
        }
        if (computeGradients)
        {
          // As the normals, without normalising: a gradient keeps its size.
          float* g = newGradients->GetPointer(3 * o);
          const float* m = gradients + 3 * i;
          if (axisAligned)
          {
            g[0] = m[0];
            g[1] = m[1];
            g[2] = m[2];
          }
          else
          {
            // Zero entries are left out: an infinite component (a spacing
            // too small for float's range) does not make 0 x inf = NaN.
            for (int r = 0; r < 3; ++r)
            {
              double v = 0.0;
              for (int c = 0; c < 3; ++c)
              {
                if (normalMatrix[r][c] != 0.0)
                {
                  v += normalMatrix[r][c] * m[c];
                }
              }
              g[r] = static_cast<float>(v);
            }
          }
        }
        if (!indexPoints.empty())
        {
          std::copy(ijk + 3 * i, ijk + 3 * i + 3, indexPoints.begin() + 3 * o);
        }
      }
    });
    const vtkIdType outPoints = static_cast<vtkIdType>(selection.NumberOfPoints);
    const vtkIdType outTriangles = static_cast<vtkIdType>(selection.NumberOfTriangles);
    if (newScalars)
    {
      for (vtkIdType i = 0; i < outPoints; ++i)
      {
        newScalars->SetComponent(ptOffset + i, 0, values[c]);
      }
    }

    unsigned char* levelOut = levels ? levels->GetPointer(0) : nullptr;
    // With the library's triangles adopted whole, only the offsets are
    // left to write.
    const bool offsetsOnly = adopted && selection.All && !levelOut;
    forRange(outTriangles, [&](vtkIdType first, vtkIdType last) {
      if (offsetsOnly)
      {
        for (vtkIdType k = first; k < last; ++k)
        {
          offs[triOffset + k] = 3 * (triOffset + k);
        }
        return;
      }
      for (vtkIdType k = first; k < last; ++k)
      {
        const vtkIdType t = selection.All ? k : selection.Triangles[static_cast<size_t>(k)];
        if (!adopted)
        {
          const int64_t* tri = tris + 3 * t;
          vtkIdType ids[3];
          for (int v = 0; v < 3; ++v)
          {
            const vtkIdType id = static_cast<vtkIdType>(tri[v]);
            ids[v] = ptOffset + (pointMap ? pointMap[id] : id);
          }
          vtkIdType* out = conn + 3 * (triOffset + k);
          out[0] = ids[0];
          out[1] = ids[flipWinding ? 2 : 1];
          out[2] = ids[flipWinding ? 1 : 2];
        }
        offs[triOffset + k] = 3 * (triOffset + k);
        if (levelOut)
        {
          levelOut[triOffset + k] = triLevels[t];
        }
      }
    });
    ptOffset += outPoints;
    triOffset += outTriangles;
    meshes[c].reset(); // release memory as soon as copied
  }
  offs[numTris] = 3 * numTris;

  vtkNew<vtkCellArray> newPolys;
  newPolys->SetData(offsets, connectivity);

  output->SetPoints(newPts);
  output->SetPolys(newPolys);
  vtkPointData* outPD = output->GetPointData();

  // Other point data, interpolated trilinearly at every output point.
  if (this->InterpolateAttributes && numPts > 0)
  {
    vtkPointData* inPD = input->GetPointData();
    vtkNew<vtkPointData> source;
    for (int a = 0; a < inPD->GetNumberOfArrays(); ++a)
    {
      vtkAbstractArray* array = inPD->GetAbstractArray(a);
      // Not the ghost flags of a distributed input: a serial run has none.
      if (array == inScalars || array == nullptr ||
        array->GetNumberOfTuples() != input->GetNumberOfPoints() ||
        (array->GetName() &&
          std::string(array->GetName()) == vtkDataSetAttributes::GhostArrayName()))
      {
        continue;
      }
      int idx = source->AddArray(array);
      for (int attr = 0; attr < vtkDataSetAttributes::NUM_ATTRIBUTES; ++attr)
      {
        if (inPD->GetAbstractAttribute(attr) == array)
        {
          source->SetActiveAttribute(idx, attr);
        }
      }
    }
    if (source->GetNumberOfArrays() > 0)
    {
      outPD->InterpolateAllocate(source, numPts);
      vtkNew<vtkIdList> cellPts;
      double weights[8];
      // Cells are clamped to the contoured extent and indexed in the
      // input's arrays (dataExtent).
      const vtkIdType sliceSize = static_cast<vtkIdType>(dataDims[0]) * dataDims[1];
      for (vtkIdType i = 0; i < numPts; ++i)
      {
        int cell[3];
        double r[3];
        for (int d = 0; d < 3; ++d)
        {
          // In global index coordinates, as the points are: every piece
          // computes the same weights for a point (bit for bit).
          const double at = indexPoints[3 * i + d];
          const double c0 = std::max<double>(
            extent[2 * d], std::min<double>(extent[2 * d + 1] - 1, std::floor(at)));
          cell[d] = static_cast<int>(c0) - dataExtent[2 * d];
          r[d] = std::max(0.0, std::min(1.0, at - c0));
        }
        const vtkIdType base = cell[0] + cell[1] * static_cast<vtkIdType>(dataDims[0]) +
          cell[2] * sliceSize;
        // Only the corners that count: a point on a face or an edge of the
        // cell (most are) takes nothing from the corners off it, not even
        // a NaN (0 x NaN would be NaN), and so gets the same value whichever
        // cell it is placed in (a distributed run clamps some to another).
        cellPts->Reset();
        int used = 0;
        for (int corner = 0; corner < 8; ++corner)
        {
          const int di = corner & 1;
          const int dj = (corner >> 1) & 1;
          const int dk = (corner >> 2) & 1;
          const double w = (di ? r[0] : 1.0 - r[0]) * (dj ? r[1] : 1.0 - r[1]) *
            (dk ? r[2] : 1.0 - r[2]);
          if (w != 0.0)
          {
            cellPts->InsertNextId(base + di + dj * dataDims[0] + dk * sliceSize);
            weights[used++] = w;
          }
        }
        outPD->InterpolatePoint(source, i, cellPts, weights);
      }
    }
  }

  if (newScalars)
  {
    int idx = outPD->AddArray(newScalars);
    outPD->SetActiveAttribute(idx, vtkDataSetAttributes::SCALARS);
  }
  if (newNormals)
  {
    // Added, then made active: SetNormals would drop an interpolated
    // array of the input that was its active normals.
    int idx = outPD->AddArray(newNormals);
    outPD->SetActiveAttribute(idx, vtkDataSetAttributes::NORMALS);
  }
  if (newGradients)
  {
    // The active vectors, as vtkFlyingEdges3D makes them (an interpolated
    // array of the input that was its active vectors stays, as a plain
    // array).
    int idx = outPD->AddArray(newGradients);
    outPD->SetActiveAttribute(idx, vtkDataSetAttributes::VECTORS);
  }
  if (levels)
  {
    output->GetCellData()->AddArray(levels);
  }

  vtkDebugMacro(<< "Created: " << numPts << " points, " << numTris << " triangles");
  this->UpdateProgress(1.0);
  return 1;
}

//------------------------------------------------------------------------------
// The piece asked for downstream is passed upstream with the ghost levels the
// filter needs, not those asked for downstream: the surface of a ghost layer
// would belong to two pieces. The piece's extent is kept in ContourExtent
// (the cells contoured) in every case: a source shared with another consumer
// that asked for ghost levels may still hold its ghost layer, which must not
// be contoured (in pvbatch under MPI, a trilinear Precise Contour after a
// refined one contoured it, overlapping the pieces). Image pieces share their
// boundary samples, but flat triangles in a piece's face cancel against those
// of the cell across it, the cubic filters read one more sample around every
// cell, and refinement that may mesh cells again on sub-cells needs the cells
// across the piece's faces (ContourGhostSamples()): the input is asked for as
// many ghost levels around the piece (for an update extent given as an
// extent, the extent grows by as many samples instead), whose cells are
// contoured but not output. BSplineInterpolating prefilters whole lines of
// samples, so it asks for the whole volume in one piece.
int vtkPreciseMarchingCubes::RequestUpdateExtent(
  vtkInformation* request, vtkInformationVector** inputVector, vtkInformationVector* outputVector)
{
  int result = this->Superclass::RequestUpdateExtent(request, inputVector, outputVector);
  vtkInformation* inInfo = inputVector[0]->GetInformationObject(0);
  vtkInformation* outInfo = outputVector->GetInformationObject(0);
  this->HasContourExtent = false;
  this->ContourWholeUnknown = false;
  if (!inInfo)
  {
    return result;
  }
  int ghostLevels = 0;
  const int ghostSamples =
    ContourGhostSamples(this->ReconstructionFilter, this->Topology, this->Epsilon,
      this->MaxLevel, this->ComputeNormals != 0 || this->ComputeGradients != 0);
  // A composite input (Group Datasets, .vtm) is asked once for all its
  // blocks, then each block is run as an input of its own, the only piece
  // of a whole volume (vtkCompositeDataPipeline): the ghost layer a piece
  // needs is asked for here, and each block's run leaves the request alone
  // (the composite input's information is where it would be set). A block
  // with a ghost layer marks it in its ghost arrays (RequestData() contours
  // its own cells). B-Spline Interpolating would need the whole volume,
  // which a composite request cannot name: a ghost layer narrows the
  // difference, RequestData() warns of it.
  if (vtkCompositeDataSet::SafeDownCast(inInfo->Get(vtkDataObject::DATA_OBJECT())))
  {
    const int numPieces = outInfo &&
        outInfo->Has(vtkStreamingDemandDrivenPipeline::UPDATE_NUMBER_OF_PIECES())
      ? outInfo->Get(vtkStreamingDemandDrivenPipeline::UPDATE_NUMBER_OF_PIECES())
      : 1;
    this->CompositePieces = std::max(1, numPieces);
    // The pipeline leaves the extent of the last block it ran on the
    // composite input (it initialises a block's request to the block's
    // whole extent), and the producer of the composite would pass it on as
    // its own request: the next update cut the source's piece out of that
    // extent again (half the surface lost when the ghost layer asked for
    // changed). A composite input is asked for by piece only.
    inInfo->Remove(vtkStreamingDemandDrivenPipeline::UPDATE_EXTENT());
    inInfo->Set(vtkStreamingDemandDrivenPipeline::UPDATE_NUMBER_OF_GHOST_LEVELS(),
      numPieces > 1 ? ghostSamples : 0);
    return result;
  }
  const bool block = IsBlockRequest(request);
  if (!block)
  {
    this->CompositePieces = 1;
  }
  if (outInfo && inInfo->Has(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT()))
  {
    int whole[6];
    inInfo->Get(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT(), whole);
    int update[6];
    std::copy(whole, whole + 6, update);
    if (inInfo->Has(vtkStreamingDemandDrivenPipeline::UPDATE_EXTENT()))
    {
      inInfo->Get(vtkStreamingDemandDrivenPipeline::UPDATE_EXTENT(), update);
    }
    const int piece = outInfo->Has(vtkStreamingDemandDrivenPipeline::UPDATE_PIECE_NUMBER())
      ? outInfo->Get(vtkStreamingDemandDrivenPipeline::UPDATE_PIECE_NUMBER())
      : 0;
    const int numPieces =
      outInfo->Has(vtkStreamingDemandDrivenPipeline::UPDATE_NUMBER_OF_PIECES())
      ? outInfo->Get(vtkStreamingDemandDrivenPipeline::UPDATE_NUMBER_OF_PIECES())
      : 1;
    // The piece as the source splits it (without ghost levels).
    this->HasContourExtent = true;
    std::copy(update, update + 6, this->ContourSplitExtent);
    this->ContourPiece = piece;
    this->ContourPieces = std::max(1, numPieces);
    int splitMode = vtkExtentTranslator::BLOCK_MODE;
    if (inInfo->Has(vtkExtentTranslator::UPDATE_SPLIT_MODE()))
    {
      splitMode = inInfo->Get(vtkExtentTranslator::UPDATE_SPLIT_MODE());
    }
    this->ContourSplitMode = splitMode;
    // An empty whole extent: the pipeline does not know the volume (a
    // source without RequestInformation, as ParaView's Programmable Source
    // without its information script), yet the source may deliver one.
    // Nothing can be asked of it; RequestData() cuts the piece from the
    // extent that arrives, taken for the whole volume (an empty piece here
    // gave an empty surface without a word).
    if (IsEmptyExtent(whole))
    {
      this->ContourWholeUnknown = true;
      // Not known before the volume arrives (RequestData() cuts the piece
      // it contours into `piece`): not a previous update's extent.
      this->ContourExtent[0] = VTK_INT_MAX;
      this->ContourExtent[1] = VTK_INT_MIN;
      // No ghost levels: the volume that arrives is taken for the whole,
      // so a ghost layer around a source's own piece would be contoured as
      // cells of the volume (with WholeInputShare's WHOLE_INPUT_ALL, twice).
      // vtkPolyDataAlgorithm asks for the exact extent, and the executive
      // would crop the volume delivered to the empty one asked for.
      if (!block)
      {
        inInfo->Set(vtkStreamingDemandDrivenPipeline::EXACT_EXTENT(), 0);
        inInfo->Set(
          vtkStreamingDemandDrivenPipeline::UPDATE_NUMBER_OF_GHOST_LEVELS(), ghostLevels);
      }
      return result;
    }
    if (numPieces > 1)
    {
      vtkNew<vtkExtentTranslator> translator;
      if (!translator->PieceToExtentThreadSafe(
            piece, numPieces, 0, update, this->ContourExtent, splitMode, 0))
      {
        // An empty piece: nothing to contour.
        this->ContourExtent[0] = VTK_INT_MAX;
        this->ContourExtent[1] = VTK_INT_MIN;
      }
    }
    else
    {
      std::copy(update, update + 6, this->ContourExtent);
    }
    if (block)
    {
      // (The composite input's request, made above, stands.)
    }
    else if (this->ReconstructionFilter == RECONSTRUCTION_BSPLINE_INTERPOLATING)
    {
      inInfo->Set(vtkStreamingDemandDrivenPipeline::UPDATE_EXTENT(), whole, 6);
      inInfo->Set(vtkStreamingDemandDrivenPipeline::UPDATE_PIECE_NUMBER(), 0);
      inInfo->Set(vtkStreamingDemandDrivenPipeline::UPDATE_NUMBER_OF_PIECES(), 1);
    }
    else if (numPieces > 1)
    {
      ghostLevels = ghostSamples;
    }
    else
    {
      int grown[6];
      for (int i = 0; i < 3; ++i)
      {
        grown[2 * i] = std::max(whole[2 * i], ShiftedIndex(update[2 * i], -ghostSamples));
        grown[2 * i + 1] = std::min(whole[2 * i + 1], ShiftedIndex(update[2 * i + 1], ghostSamples));
      }
      inInfo->Set(vtkStreamingDemandDrivenPipeline::UPDATE_EXTENT(), grown, 6);
    }
  }
  if (!block)
  {
    inInfo->Set(vtkStreamingDemandDrivenPipeline::UPDATE_NUMBER_OF_GHOST_LEVELS(), ghostLevels);
  }
  return result;
}

//------------------------------------------------------------------------------
int vtkPreciseMarchingCubes::FillInputPortInformation(int, vtkInformation* info)
{
  info->Set(vtkAlgorithm::INPUT_REQUIRED_DATA_TYPE(), "vtkImageData");
  return 1;
}

//------------------------------------------------------------------------------
void vtkPreciseMarchingCubes::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);

  this->ContourValues->PrintSelf(os, indent.GetNextIndent());

  os << indent << "Compute Normals: " << (this->ComputeNormals ? "On\n" : "Off\n");
  os << indent << "Compute Gradients: " << (this->ComputeGradients ? "On\n" : "Off\n");
  os << indent << "Compute Scalars: " << (this->ComputeScalars ? "On\n" : "Off\n");
  os << indent << "Interpolate Attributes: " << (this->InterpolateAttributes ? "On\n" : "Off\n");
  os << indent << "Compute Levels: " << (this->ComputeLevels ? "On\n" : "Off\n");
  os << indent << "ArrayComponent: " << this->ArrayComponent << endl;
  os << indent << "Output Points Precision: " << this->OutputPointsPrecision << "\n";
  os << indent << "Epsilon: " << this->Epsilon << "\n";
  os << indent << "MaxLevel: " << this->MaxLevel << "\n";
  os << indent << "Rule: " << this->GetRuleAsString() << "\n";
  os << indent << "ReconstructionFilter: " << this->GetReconstructionFilterAsString() << "\n";
  os << indent << "Topology: " << this->GetTopologyAsString() << "\n";
  os << indent << "NormalMode: " << this->GetNormalModeAsString() << "\n";
  os << indent << "MaxTriangles: " << this->MaxTriangles << "\n";
  os << indent << "NumberOfThreads: " << this->NumberOfThreads << "\n";
  os << indent << "UseSMPTools: " << (this->UseSMPTools ? "On" : "Off") << "\n";
  os << indent << "NumberOfMCTriangles: " << this->NumberOfMCTriangles << "\n";
  os << indent << "NumberOfRefinedTriangles: " << this->NumberOfRefinedTriangles << "\n";
  os << indent << "NumberOfAmbiguousCells: " << this->NumberOfAmbiguousCells << "\n";
  os << indent << "NumberOfSkippedCells: " << this->NumberOfSkippedCells << "\n";
  os << indent << "MaxLevelReached: " << this->MaxLevelReached << "\n";
  os << indent << "MeanLevel: " << this->MeanLevel << "\n";
  os << indent << "NumberOfSamplesEvaluated: " << this->NumberOfSamplesEvaluated << "\n";
  os << indent << "NumberOfSplitPoints: " << this->NumberOfSplitPoints << "\n";
  os << indent << "NumberOfProjectionFailures: " << this->NumberOfProjectionFailures << "\n";
  os << indent << "NumberOfFacesAboveEpsilon: " << this->NumberOfFacesAboveEpsilon << "\n";
  os << indent << "NumberOfCellsRefinedOnFacesOnly: " << this->NumberOfCellsRefinedOnFacesOnly
     << "\n";
  os << indent << "NumberOfRecutPolygons: " << this->NumberOfRecutPolygons << "\n";
  os << indent << "NumberOfCellsOnSubcells: " << this->NumberOfCellsOnSubcells << "\n";
  os << indent << "BudgetReached: " << (this->BudgetReached ? "true" : "false") << "\n";
  os << indent << "ExecutionTime: " << this->ExecutionTime << "\n";
  os << indent << "NumberOfExecutions: " << this->NumberOfExecutions << "\n";
  // The piece state RequestUpdateExtent() left for RequestData().
  os << indent << "ContourExtent: ";
  if (this->HasContourExtent)
  {
    for (int i = 0; i < 6; ++i)
    {
      os << this->ContourExtent[i] << (i < 5 ? " " : "");
    }
    os << (this->ContourWholeUnknown ? " (whole extent unknown)" : "") << "\n";
  }
  else
  {
    os << "(none)\n";
  }
  os << indent << "ContourPiece: " << this->ContourPiece << " of " << this->ContourPieces << "\n";
  os << indent << "WholeInputShare: " << this->WholeInputShare << "\n";
}
