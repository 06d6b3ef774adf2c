/*=========================================================================

  Program:   PreciseMC
  Module:    vtkPreciseMarchingCubes.h

  Copyright (c) the PreciseMC authors
  All rights reserved.
  Licensed under the MIT or Apache-2.0 license, at your option.

     This software is distributed WITHOUT ANY WARRANTY; without even
     the implied warranty of MERCHANTABILITY or FITNESS FOR A PARTICULAR
     PURPOSE.

=========================================================================*/
/**
 * @class   vtkPreciseMarchingCubes
 * @brief   isosurface of a volume that follows the trilinear interpolant
 *
 * vtkPreciseMarchingCubes extracts isosurfaces from 3D image data in two
 * steps, after Allamandri, Cignoni, Montani and Scopigno, "Adaptively
 * adjusting Marching Cubes output to fit a trilinear reconstruction
 * filter":
 *
 * 1. Marching Cubes runs with the ambiguities of the classic case table
 *    resolved so that, inside every cell, the mesh has the topology of the
 *    isosurface of the trilinear interpolant of the samples (Topology
 *    Trilinear, the default), or with the case table of vtkMarchingCubes
 *    (Topology Classic).
 * 2. Every triangle is refined adaptively: sample points on the triangle
 *    (edge midpoints, centroid; see SetRule()) farther than Epsilon (in
 *    cell units) from the trilinear isosurface become new vertices, moved
 *    onto the isosurface along the gradient line, recursively up to
 *    MaxLevel.
 *
 * The output is a welded, consistently oriented triangle mesh: the normal
 * (p1 - p0) x (p2 - p0) of each triangle points towards lower scalar
 * values, as in vtkMarchingCubes. With Topology Classic and Epsilon 0 the
 * output is the surface of vtkMarchingCubes (same points, triangles and
 * winding; point order differs), except where samples equal the isovalue:
 * the flat triangles that two cells emit there on a shared face, in
 * opposite orientations, cancel in pairs (vtkMarchingCubes keeps both, a
 * double-sided sheet of zero thickness).
 *
 * The interface follows vtkFlyingEdges3D: several contour values may be
 * given and their surfaces are appended into one output; point normals,
 * point gradients, point scalars (the contour value) and the other point data (interpolated
 * trilinearly at every output point, refined points included) are
 * optional. A per-triangle "RefinementLevel" cell array records how often
 * each triangle was subdivided (0 = Marching Cubes triangle).
 *
 * Any scalar type is contoured in place (no conversion or copy of the
 * volume; only an array without VTK's standard array-of-structures memory
 * layout is copied first), including one component of a multi-component
 * array (see SetArrayComponent()). Images with extents that do not start
 * at 0, any finite non-zero spacing (negative too) and a direction matrix
 * are supported (zero or non-finite spacing or origin is an error): points
 * computed for pieces
 * of a volume that share a layer of samples are bit-identical.
 *
 * In a distributed pipeline each piece contours the input cropped to the
 * requested update extent. Image pieces share their boundary samples, so
 * the union of the pieces' surfaces is the surface of the whole volume,
 * without cracks or overlaps (a piece that is a single layer of samples
 * holds no cell and has an empty output; a 2D input is an error). The
 * filter always asks for at least one ghost level, contours the cells
 * across the piece's faces too and keeps only the triangles of the
 * piece's own cells, for three reasons: where a plane of samples equals
 * the isovalue, the cells on its two sides emit the same flat triangles
 * with opposite orientations, which cancel, so a piece cut along such a
 * plane must see the cells across it; normals and gradients at a point
 * on a piece's face read the samples beyond it; and refining with the trilinear
 * topology from MaxLevel 3 up, a cell where refinement stalls is meshed
 * again on sub-cells, whose strips in a face cancel against those of a
 * neighbour meshed again too. The cubic filters read one more layer of
 * samples around every cell, so they ask for two ghost levels (the second
 * gives the ghost cells next to the piece their whole neighbourhood;
 * BSplineInterpolating, whose prefilter is global, asks for the whole
 * volume). The union is
 * in every case exactly the serial surface (see
 * SetReconstructionFilter()), unless MaxTriangles lowers a piece's level:
 * each piece meets the cap on its own (see SetMaxTriangles()). An input
 * that an upstream filter split its own way (neither the piece asked for
 * nor the whole volume, as Resample To Image delivers) is contoured on its
 * own cells (those its ghost array does not mark as duplicates), so the
 * pieces still cover the volume once. A piece grown by the ghost layer
 * asked for that carries a point ghost array only (vtkImageChangeInformation
 * and vtkImageTranslateExtent pass the point data on, not the cell data)
 * is the piece asked for when its cells without a corner flagged
 * DUPLICATEPOINT are that piece: the rest is its ghost layer. Without the ghost layer the run
 * needs, the surface next to the cuts may then differ from the serial one,
 * and the filter warns (not for flat triangles on a cut where samples
 * equal the isovalue); so it does for an input that is the piece asked for
 * but without the ghost layer asked with it (a source that ignores ghost
 * levels). A composite input (image blocks: a multiblock, Group Datasets)
 * is asked for the same ghost layer, and each block is contoured on its
 * own cells, those its ghost array does not mark as duplicates; only
 * BSplineInterpolating cannot have the whole volume there, and warns that
 * its surface differs. Cells the input's cell ghost array flags HIDDENCELL, or with a
 * corner its point ghost array flags HIDDENPOINT (AMR blanking), make no
 * triangles, as in vtkContourFilter on a vtkUniformGrid. InterpolateAttributes gives every point the same
 * values in every piece, and never interpolates the input's ghost flags.
 *
 * The work is done by the PreciseMC library (Rust) through its C API, in
 * parallel over all cores unless NumberOfThreads is set, or on
 * vtkSMPTools with UseSMPTools on; the output does not depend on the
 * number of threads.
 *
 * @warning
 * Refinement can multiply the number of triangles by up to 4^MaxLevel
 * (rules A and A1) or 6^MaxLevel (rules A2 and B) in the worst case;
 * SetMaxTriangles() caps the output (refinement then stops at the highest
 * level that fits, see GetBudgetReached()), and without a cap the library
 * still stops refinement at 250 million triangles of a contour value.
 *
 * @warning
 * Cells with a NaN or infinite corner sample produce no triangles.
 *
 * @warning
 * The statistics (GetNumberOfMCTriangles() and the like) describe the last
 * execution, summed (or maximised) over the contour values. On a piece
 * contoured with a ghost layer or with hidden cells (see above), the counts
 * of the library (all but NumberOfRefinedTriangles, MaxLevelReached and
 * MeanLevel, which describe the output) include the ghost and hidden cells.
 *
 * @sa
 * vtkMarchingCubes vtkFlyingEdges3D vtkContourFilter vtkImageTransform
 */

#ifndef vtkPreciseMarchingCubes_h
#define vtkPreciseMarchingCubes_h

#include "vtkContourValues.h"        // Passes calls through
#include "vtkPreciseMCModule.h"      // For export macro
#include "vtkPolyDataAlgorithm.h"

class vtkImageData;

class VTKPRECISEMC_EXPORT vtkPreciseMarchingCubes : public vtkPolyDataAlgorithm
{
public:
  static vtkPreciseMarchingCubes* New();
  vtkTypeMacro(vtkPreciseMarchingCubes, vtkPolyDataAlgorithm);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  /**
   * Because we delegate to vtkContourValues.
   */
  vtkMTimeType GetMTime() override;

  /**
   * The PreciseMC library's code for samples of VTK type `vtkType` (one of
   * the PMC_SCALAR_TYPE_* values of precisemc.h), or -1 when the library
   * cannot read that type (bit, string and variant arrays). For tools that
   * hand VTK arrays to the C API themselves.
   */
  static int LibraryScalarType(int vtkType);

  /**
   * Frees the buffers the PreciseMC library keeps between executions and
   * returns their size in bytes. Every execution hands its working
   * buffers (and the library's arrays once copied into the output) to
   * process-wide bins, at most 64 MiB in all, shared by every instance of
   * the filter, so that the next execution writes into memory already
   * mapped instead of faulting fresh pages in. Call this after a burst of
   * executions when the memory is wanted elsewhere; the next execution
   * then runs on fresh memory, with the same output. Also stops the
   * helper threads the library keeps between executions (each returns by
   * itself after 1 s without work) unless an execution is using them.
   * Thread-safe: executions running meanwhile are not affected.
   */
  static vtkTypeUInt64 ReleaseRetainedMemory();

  /**
   * How ambiguous cells are triangulated (see SetTopology()).
   */
  enum TopologyModes
  {
    TOPOLOGY_TRILINEAR = 0,
    TOPOLOGY_CLASSIC = 1
  };

  /**
   * Where a triangle is sampled to decide whether to split it (section 3.1
   * of the paper, see SetRule()).
   */
  enum RefinementRules
  {
    RULE_A = 0,
    RULE_A1 = 1,
    RULE_A2 = 2,
    RULE_B = 3
  };

  /**
   * The reconstruction filter whose isosurface refinement follows (see
   * SetReconstructionFilter()).
   */
  enum ReconstructionFilters
  {
    RECONSTRUCTION_TRILINEAR = 0,
    RECONSTRUCTION_CATMULL_ROM = 1,
    RECONSTRUCTION_BSPLINE = 2,
    RECONSTRUCTION_BSPLINE_INTERPOLATING = 3
  };

  /**
   * How normals are computed when ComputeNormals is on (see
   * SetNormalMode()).
   */
  enum NormalModes
  {
    NORMALS_GRADIENT = 1,
    NORMALS_CENTRAL_DIFFERENCE = 2
  };

  ///@{
  /**
   * Set/Get the computation of point normals (unit vectors pointing towards
   * lower scalar values, like vtkMarchingCubes). How they are computed is
   * set by NormalMode. Default is on.
   */
  vtkSetMacro(ComputeNormals, vtkTypeBool);
  vtkGetMacro(ComputeNormals, vtkTypeBool);
  vtkBooleanMacro(ComputeNormals, vtkTypeBool);
  ///@}

  ///@{
  /**
   * Set/Get the computation of point gradients, as in vtkFlyingEdges3D: a
   * 3-component float point array "Gradients" holding the scalar gradient
   * at each output point, un-normalised, pointing towards higher scalar
   * values, in scalar units per world length (with a direction matrix D,
   * in world axes: D^-T times the gradient along the image axes). They are
   * computed as the normals are (NormalMode, also when ComputeNormals is
   * off), so that where both are on each normal is the negated, normalised
   * gradient. A component beyond float's range is infinite. The array is
   * made the active vectors, as vtkFlyingEdges3D does. Default is off.
   */
  vtkSetMacro(ComputeGradients, vtkTypeBool);
  vtkGetMacro(ComputeGradients, vtkTypeBool);
  vtkBooleanMacro(ComputeGradients, vtkTypeBool);
  ///@}

  ///@{
  /**
   * Set/Get the computation of point scalars: every point gets the contour
   * value of its surface, in an array of the type and name of the input
   * scalars, made the active scalars of the output. Default is on.
   */
  vtkSetMacro(ComputeScalars, vtkTypeBool);
  vtkGetMacro(ComputeScalars, vtkTypeBool);
  vtkBooleanMacro(ComputeScalars, vtkTypeBool);
  ///@}

  ///@{
  /**
   * Indicate whether to interpolate the other point data arrays of the
   * input. Each output point (refined points included) gets the trilinear
   * interpolation of the arrays at its position. Default is off.
   */
  vtkSetMacro(InterpolateAttributes, vtkTypeBool);
  vtkGetMacro(InterpolateAttributes, vtkTypeBool);
  vtkBooleanMacro(InterpolateAttributes, vtkTypeBool);
  ///@}

  ///@{
  /**
   * Set/Get the generation of the cell array "RefinementLevel" (unsigned
   * char): the refinement level of each triangle, 0 for triangles straight
   * from Marching Cubes. Default is off.
   */
  vtkSetMacro(ComputeLevels, vtkTypeBool);
  vtkGetMacro(ComputeLevels, vtkTypeBool);
  vtkBooleanMacro(ComputeLevels, vtkTypeBool);
  ///@}

  /**
   * Set a particular contour value at contour number i. The index i ranges
   * between 0<=i<NumberOfContours. A new filter has one contour value,
   * 0.0 (as vtkMarchingCubes).
   */
  void SetValue(int i, double value) { this->ContourValues->SetValue(i, value); }

  /**
   * Get the ith contour value.
   */
  double GetValue(int i) { return this->ContourValues->GetValue(i); }

  /**
   * Get a pointer to an array of contour values. There will be
   * GetNumberOfContours() values in the list.
   */
  double* GetValues() VTK_SIZEHINT(GetNumberOfContours())
  {
    return this->ContourValues->GetValues();
  }

  /**
   * Fill a supplied list with contour values. There will be
   * GetNumberOfContours() values in the list. Make sure you allocate
   * enough memory to hold the list.
   */
  void GetValues(double* contourValues) { this->ContourValues->GetValues(contourValues); }

  /**
   * Set the number of contours to place into the list. You only really
   * need to use this method to reduce list size. The method SetValue()
   * will automatically increase list size as needed.
   */
  void SetNumberOfContours(int number) { this->ContourValues->SetNumberOfContours(number); }

  /**
   * Get the number of contours in the list of contour values.
   */
  vtkIdType GetNumberOfContours() { return this->ContourValues->GetNumberOfContours(); }

  /**
   * Generate numContours equally spaced contour values between specified
   * range. Contour values will include min/max range values.
   */
  void GenerateValues(int numContours, double range[2])
  {
    this->ContourValues->GenerateValues(numContours, range);
  }

  /**
   * Generate numContours equally spaced contour values between specified
   * range. Contour values will include min/max range values.
   */
  void GenerateValues(int numContours, double rangeStart, double rangeEnd)
  {
    this->ContourValues->GenerateValues(numContours, rangeStart, rangeEnd);
  }

  ///@{
  /**
   * Set/get which component of the scalar array to contour on; defaults to
   * 0. The component is read in place (no copy of the volume, unless the
   * array lacks the standard array-of-structures layout).
   */
  vtkSetMacro(ArrayComponent, int);
  vtkGetMacro(ArrayComponent, int);
  ///@}

  ///@{
  /**
   * Set/get the desired precision for the output points. See
   * vtkAlgorithm::DesiredOutputPrecision for the available settings.
   * DEFAULT_PRECISION and SINGLE_PRECISION give float points (like
   * vtkMarchingCubes), DOUBLE_PRECISION gives the points exactly as
   * computed. Where the input's world coordinates go beyond float's range
   * (about 3.4e38), DEFAULT_PRECISION gives double points and
   * SINGLE_PRECISION is an error (float points would be infinite). Where
   * float cannot tell a cell's points apart (a cell side below float's
   * least normal number, about 1.2e-38, or spanning fewer float steps at
   * the largest world coordinate than 2^MaxLevel, e.g. an origin of 1e7
   * with unit spacing), DEFAULT_PRECISION gives double points too and
   * SINGLE_PRECISION warns. Where even double points round by more than
   * 1e-4 of a cell (a spacing below 2^-40 times the world coordinates
   * along its axis, e.g. an origin of 1e17 with unit spacing), the filter
   * warns whatever the precision. The largest world coordinate is that of the
   * whole volume (the pipeline's whole extent), so that every piece of a
   * distributed run makes the serial run's choice. Default
   * DEFAULT_PRECISION; a value outside SINGLE_PRECISION..DEFAULT_PRECISION
   * is clamped into it, with a warning.
   */
  virtual void SetOutputPointsPrecision(int value);
  virtual int GetOutputPointsPrecisionMinValue() { return SINGLE_PRECISION; }
  virtual int GetOutputPointsPrecisionMaxValue() { return DEFAULT_PRECISION; }
  vtkGetMacro(OutputPointsPrecision, int);
  ///@}

  ///@{
  /**
   * Set/Get the largest allowed distance, in cell units (edges of a cell of
   * index space), between a tested sample point of a triangle and the
   * isosurface of the reconstruction filter (trilinear by default, see
   * SetReconstructionFilter()). Triangles with a sample point farther than this
   * are split. 0 turns refinement off (plain Marching Cubes). Must be
   * finite and non-negative. Default 0.01.
   */
  vtkSetMacro(Epsilon, double);
  vtkGetMacro(Epsilon, double);
  ///@}

  ///@{
  /**
   * Set/Get the maximum refinement level (0 = plain Marching Cubes, at
   * most 10). Default 5. A value outside 0..10 is clamped into it, with a
   * warning (the C API and the command-line tool refuse it).
   */
  virtual void SetMaxLevel(int value);
  virtual int GetMaxLevelMinValue() { return 0; }
  virtual int GetMaxLevelMaxValue() { return 10; }
  vtkGetMacro(MaxLevel, int);
  ///@}

  ///@{
  /**
   * Set/Get the refinement rule: RULE_A (edge midpoints only), RULE_A1
   * (then the centroid when no edge splits; the default), RULE_A2 (then a
   * displaced centroid) or RULE_B (midpoints and centroid at once). A
   * value outside RULE_A..RULE_B (0..3) is clamped into it, with a
   * warning.
   */
  virtual void SetRule(int value);
  virtual int GetRuleMinValue() { return RULE_A; }
  virtual int GetRuleMaxValue() { return RULE_B; }
  vtkGetMacro(Rule, int);
  void SetRuleToA() { this->SetRule(RULE_A); }
  void SetRuleToA1() { this->SetRule(RULE_A1); }
  void SetRuleToA2() { this->SetRule(RULE_A2); }
  void SetRuleToB() { this->SetRule(RULE_B); }
  const char* GetRuleAsString();
  ///@}

  ///@{
  /**
   * Set/Get the reconstruction filter whose isosurface the split points of
   * refinement are moved onto (Epsilon is measured to that isosurface, in
   * cell units):
   * - RECONSTRUCTION_TRILINEAR (the default): the trilinear interpolant of
   *   each cell, as in the paper.
   * - RECONSTRUCTION_CATMULL_ROM: tricubic Catmull-Rom (interpolates the
   *   samples, C1).
   * - RECONSTRUCTION_BSPLINE: tricubic B-spline of the samples (C2,
   *   smoothing: it does not pass through the samples).
   * - RECONSTRUCTION_BSPLINE_INTERPOLATING: tricubic B-spline through the
   *   samples (prefiltered, C2); allocates one double per sample.
   *
   * Marching Cubes' topology always comes from the samples (the trilinear
   * decision); with a cubic filter and refinement on, its edge vertices
   * first move along their grid edge onto the cubic isosurface (where the
   * filter brackets one there), then the split points follow it; the
   * mesh stays welded,
   * watertight and independent of the number of threads. Nothing is
   * guaranteed about the topology of the cubic isosurface. The cubic
   * filters read the 4x4x4 samples around a cell (the border sample
   * repeated at the volume's border), so in a distributed pipeline they
   * request two ghost levels of input (BSplineInterpolating, whose
   * prefilter couples all samples of a line, requests the whole volume on
   * every piece) and contour only the piece's own cells: the union of the
   * pieces is identical to the serial surface. A value outside 0..3 is
   * clamped into it, with a warning.
   */
  virtual void SetReconstructionFilter(int value);
  virtual int GetReconstructionFilterMinValue() { return RECONSTRUCTION_TRILINEAR; }
  virtual int GetReconstructionFilterMaxValue() { return RECONSTRUCTION_BSPLINE_INTERPOLATING; }
  vtkGetMacro(ReconstructionFilter, int);
  void SetReconstructionFilterToTrilinear()
  {
    this->SetReconstructionFilter(RECONSTRUCTION_TRILINEAR);
  }
  void SetReconstructionFilterToCatmullRom()
  {
    this->SetReconstructionFilter(RECONSTRUCTION_CATMULL_ROM);
  }
  void SetReconstructionFilterToBSpline() { this->SetReconstructionFilter(RECONSTRUCTION_BSPLINE); }
  void SetReconstructionFilterToBSplineInterpolating()
  {
    this->SetReconstructionFilter(RECONSTRUCTION_BSPLINE_INTERPOLATING);
  }
  /**
   * The reconstruction filter's name: "Trilinear", "CatmullRom", "BSpline"
   * or "BSplineInterpolating".
   */
  const char* GetReconstructionFilterAsString();
  ///@}

  ///@{
  /**
   * Set/Get the topology mode: TOPOLOGY_TRILINEAR (the default; inside
   * every cell the mesh has the topology of the trilinear isosurface,
   * tunnels included) or TOPOLOGY_CLASSIC (the case table of
   * vtkMarchingCubes; refined, a cell whose table patch joins the
   * crossings otherwise than the trilinear interpolant is split on its
   * faces' edges only). A value outside 0..1 is clamped into it, with a
   * warning.
   */
  virtual void SetTopology(int value);
  virtual int GetTopologyMinValue() { return TOPOLOGY_TRILINEAR; }
  virtual int GetTopologyMaxValue() { return TOPOLOGY_CLASSIC; }
  vtkGetMacro(Topology, int);
  void SetTopologyToTrilinear() { this->SetTopology(TOPOLOGY_TRILINEAR); }
  void SetTopologyToClassic() { this->SetTopology(TOPOLOGY_CLASSIC); }
  const char* GetTopologyAsString();
  ///@}

  ///@{
  /**
   * Set/Get how normals (ComputeNormals) and gradients (ComputeGradients)
   * are computed:
   * NORMALS_GRADIENT (the exact gradient of the trilinear interpolant at
   * the point; the default) or NORMALS_CENTRAL_DIFFERENCE (central
   * differences at the grid points interpolated to the point, like
   * vtkMarchingCubes). A value outside NORMALS_GRADIENT..
   * NORMALS_CENTRAL_DIFFERENCE (1..2) is clamped into it, with a warning.
   * (There is no "none" mode here: ComputeNormals and ComputeGradients
   * off compute neither; the C API's PMC_NORMALS_NONE is 0, which this
   * setter turns into NORMALS_GRADIENT.)
   */
  virtual void SetNormalMode(int value);
  virtual int GetNormalModeMinValue() { return NORMALS_GRADIENT; }
  virtual int GetNormalModeMaxValue() { return NORMALS_CENTRAL_DIFFERENCE; }
  vtkGetMacro(NormalMode, int);
  void SetNormalModeToGradient() { this->SetNormalMode(NORMALS_GRADIENT); }
  void SetNormalModeToCentralDifference() { this->SetNormalMode(NORMALS_CENTRAL_DIFFERENCE); }
  const char* GetNormalModeAsString();
  ///@}

  ///@{
  /**
   * Set/Get a cap on the number of output triangles of each contour value;
   * refinement stops at the highest level that fits (the Marching Cubes
   * triangles are always kept, whatever the cap). 0 (the default) means
   * no cap but the library's own, 250 million. Only the output counts:
   * the triangles of a piece's ghost layer and of hidden cells, contoured
   * and dropped, do not (the library's cap counts them, so when it lowers
   * the level the filter contours again at the levels above, one at a
   * time, while the triangles kept fit). A piece of a distributed
   * run meets the cap on its own, with its own triangles: two pieces
   * stopping at different levels do not meet along their cut, and the
   * filter warns when the cap lowered the level of a piece (raise the cap,
   * or contour the volume in one piece).
   */
  vtkSetMacro(MaxTriangles, vtkTypeUInt64);
  vtkGetMacro(MaxTriangles, vtkTypeUInt64);
  ///@}

  ///@{
  /**
   * Set/Get the number of worker threads of the library; 0 (the default)
   * uses all cores. Unless it is 1 (with UseSMPTools off), a large output
   * is also copied into the vtkPolyData through vtkSMPTools, with the
   * backend and thread count the application set for it: its points from
   * 65 536 points, its triangles from 65 536 triangles. The output does
   * not depend on it. At most 4096 (the library's PMC_MAX_THREADS): a
   * larger value is clamped to it, a negative one to 0 (all cores), with
   * a warning (the C API and the command-line tool refuse them).
   */
  virtual void SetNumberOfThreads(int value);
  virtual int GetNumberOfThreadsMinValue() { return 0; }
  virtual int GetNumberOfThreadsMaxValue() { return 4096; }
  vtkGetMacro(NumberOfThreads, int);
  ///@}

  ///@{
  /**
   * Set/Get whether the library's parallel steps run as vtkSMPTools tasks,
   * on the backend and thread count the application chose for
   * vtkSMPTools (TBB's pool, for instance, whose threads persist between
   * executions), instead of on the library's own helper threads (which it
   * keeps a second between executions). When on, NumberOfThreads is not
   * used: the volume is cut for vtkSMPTools::GetEstimatedNumberOfThreads()
   * workers (on the Sequential backend everything runs on the calling
   * thread). Progress is reported, and AbortExecute honoured, after the
   * tasks run on the calling thread: TBB runs some there; on the STDThread
   * backend, which
   * runs none of a For there, the calling thread takes tasks beside the
   * vtkSMPTools workers (one fewer of them, from a helper thread) so that
   * a long refinement still reports progress and stops when aborted.
   * Default off. The output does not depend on it.
   */
  vtkSetMacro(UseSMPTools, vtkTypeBool);
  vtkGetMacro(UseSMPTools, vtkTypeBool);
  vtkBooleanMacro(UseSMPTools, vtkTypeBool);
  ///@}

  ///@{
  /**
   * Statistics of the last execution, summed over the contour values
   * (maximised for GetMaxLevelReached(), averaged over all output
   * triangles for GetMeanLevel()).
   * - NumberOfMCTriangles: triangles produced by Marching Cubes, counted
   *   before the flat triangles that cancel in pairs across a plane of
   *   samples equal to the isovalue are dropped (the output can hold fewer).
   * - NumberOfRefinedTriangles: triangles in the output.
   * - NumberOfAmbiguousCells: cells whose topology was decided by the
   *   trilinear test (0 with Topology Classic).
   * - NumberOfSkippedCells: cells with a NaN or infinite sample (with the
   *   cubic filters, in their 4x4x4 neighbourhood), which produce no
   *   triangles.
   * - MaxLevelReached / MeanLevel: refinement level of output triangles.
   * - NumberOfSamplesEvaluated / NumberOfSplitPoints: sample points tested
   *   and inserted, per cell (a point on a face that two cells share counts
   *   in both).
   * - NumberOfProjectionFailures: sample points for which no point of the
   *   isosurface was found along the gradient line within the cell, or
   *   only one farther away than the edge (triangle) sampled.
   * - NumberOfFacesAboveEpsilon: triangles at MaxLevel still farther than
   *   Epsilon at a sample point.
   * - NumberOfCellsRefinedOnFacesOnly: cells refined on their faces'
   *   edges only (their interior may stay farther than Epsilon): their
   *   refined patch was unsound (split points meeting, a patch turned
   *   inside out), or, with Topology Classic, their table patch is not
   *   the trilinear interpolant's.
   * - NumberOfRecutPolygons: Marching Cubes polygons cut along other
   *   diagonals before refining, because refinement could not bring a
   *   diagonal of the case table's onto the isosurface (0 with
   *   refinement off).
   * - NumberOfCellsOnSubcells: cells where refinement stalled on a fold
   *   or neck of the isosurface and that were meshed again on 4x4x4
   *   sub-cells (trilinear filter and topology, MaxLevel >= 3 only).
   * - BudgetReached: whether MaxTriangles (or the library's safety cap)
   *   stopped refinement early for some contour value.
   * - ExecutionTime: wall time of the contouring, seconds: the library
   *   calls for every contour value, with the selection of the piece's own
   *   triangles and the statistics (not the copy into the output).
   */
  vtkGetMacro(NumberOfMCTriangles, vtkTypeUInt64);
  vtkGetMacro(NumberOfRefinedTriangles, vtkTypeUInt64);
  vtkGetMacro(NumberOfAmbiguousCells, vtkTypeUInt64);
  vtkGetMacro(NumberOfSkippedCells, vtkTypeUInt64);
  vtkGetMacro(MaxLevelReached, int);
  vtkGetMacro(MeanLevel, double);
  vtkGetMacro(NumberOfSamplesEvaluated, vtkTypeUInt64);
  vtkGetMacro(NumberOfSplitPoints, vtkTypeUInt64);
  vtkGetMacro(NumberOfProjectionFailures, vtkTypeUInt64);
  vtkGetMacro(NumberOfFacesAboveEpsilon, vtkTypeUInt64);
  vtkGetMacro(NumberOfCellsRefinedOnFacesOnly, vtkTypeUInt64);
  vtkGetMacro(NumberOfRecutPolygons, vtkTypeUInt64);
  vtkGetMacro(NumberOfCellsOnSubcells, vtkTypeUInt64);
  vtkGetMacro(BudgetReached, bool);
  vtkGetMacro(ExecutionTime, double);
  ///@}

  /**
   * The number of times RequestData() ran and reached the library, for
   * checking that an unchanged pipeline does not re-execute.
   */
  vtkGetMacro(NumberOfExecutions, vtkTypeUInt64);

protected:
  vtkPreciseMarchingCubes();
  ~vtkPreciseMarchingCubes() override;

  int RequestData(vtkInformation*, vtkInformationVector**, vtkInformationVector*) override;
  int RequestUpdateExtent(vtkInformation*, vtkInformationVector**, vtkInformationVector*) override;
  int FillInputPortInformation(int port, vtkInformation* info) override;

  void ResetStatistics();

  // `value` clamped into [lo, hi]; warns, naming the setting, when it was
  // outside (vtkSetClampMacro's clamp, which is silent).
  int ClampSetting(const char* name, int value, int lo, int hi);

  vtkContourValues* ContourValues;
  vtkTypeBool ComputeNormals;
  vtkTypeBool ComputeGradients;
  vtkTypeBool ComputeScalars;
  vtkTypeBool InterpolateAttributes;
  vtkTypeBool ComputeLevels;
  int ArrayComponent;
  int OutputPointsPrecision;

  double Epsilon;
  int MaxLevel;
  int Rule;
  int ReconstructionFilter;
  int Topology;
  int NormalMode;
  vtkTypeUInt64 MaxTriangles;
  int NumberOfThreads;
  vtkTypeBool UseSMPTools;

  vtkTypeUInt64 NumberOfMCTriangles;
  vtkTypeUInt64 NumberOfRefinedTriangles;
  vtkTypeUInt64 NumberOfAmbiguousCells;
  vtkTypeUInt64 NumberOfSkippedCells;
  int MaxLevelReached;
  double MeanLevel;
  vtkTypeUInt64 NumberOfSamplesEvaluated;
  vtkTypeUInt64 NumberOfSplitPoints;
  vtkTypeUInt64 NumberOfProjectionFailures;
  vtkTypeUInt64 NumberOfFacesAboveEpsilon;
  vtkTypeUInt64 NumberOfCellsRefinedOnFacesOnly;
  vtkTypeUInt64 NumberOfRecutPolygons;
  vtkTypeUInt64 NumberOfCellsOnSubcells;
  bool BudgetReached;
  double ExecutionTime;
  vtkTypeUInt64 NumberOfExecutions;

  // The extent whose cells are contoured, set by RequestUpdateExtent() (the
  // input may hold a ghost layer more); when HasContourExtent is false (no
  // whole extent known) the update extent is contoured.
  int ContourExtent[6];
  bool HasContourExtent;
  // The input's whole extent is empty (the pipeline does not know the
  // volume): RequestData() takes the extent that arrives for it and cuts
  // ContourExtent from it.
  bool ContourWholeUnknown;
  // How RequestUpdateExtent() split the volume for ContourExtent: the
  // extent split, the piece, the number of pieces and the split mode of
  // vtkExtentTranslator (ContourPieces 1: not split). RequestData() tells
  // from them whether the input arrived split that way.
  int ContourSplitExtent[6];
  int ContourPiece;
  int ContourPieces;
  int ContourSplitMode;
  // The number of pieces a composite input (its blocks run one by one, each
  // as the only piece) was asked for; 1 for an image input.
  int CompositePieces;

  // What a piece of a distributed run (ContourPieces > 1) does with an
  // input that is the whole volume with no cell marked as a duplicate: cut
  // it as asked (every piece holds the whole volume: SetInputData, a
  // source that ignores pieces; the default), contour all of it (this piece
  // alone holds the volume, the others nothing: a reader that reads on the
  // first process only), or nothing (another piece holding it contours
  // it). A plain VTK filter cannot tell the cases apart; a subclass that
  // can (ParaView's, asking the other processes) sets it before
  // RequestData() of this class runs.
  enum WholeInputShares
  {
    WHOLE_INPUT_AS_ASKED = 0,
    WHOLE_INPUT_ALL = 1,
    WHOLE_INPUT_NONE = 2
  };
  int WholeInputShare;

private:
  // RequestData() without its guard against VTK's out-of-memory
  // exceptions.
  int Contour(vtkInformationVector** inputVector, vtkInformationVector* outputVector);

  vtkPreciseMarchingCubes(const vtkPreciseMarchingCubes&) = delete;
  void operator=(const vtkPreciseMarchingCubes&) = delete;
};

#endif
