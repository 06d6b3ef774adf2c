/*=========================================================================

  Program:   PreciseMC
  Module:    vtkPVPreciseMarchingCubes.h

  Copyright (c) the PreciseMC authors
  All rights reserved.
  Licensed under the MIT or Apache-2.0 license, at your option.

     This software is distributed WITHOUT ANY WARRANTY; without even
     the implied warranty of MERCHANTABILITY or FITNESS FOR A PARTICULAR
     PURPOSE.

=========================================================================*/
/**
 * @class   vtkPVPreciseMarchingCubes
 * @brief   vtkPreciseMarchingCubes as seen by ParaView's server manager
 *
 * The ParaView plugin's proxy ("Precise Contour") drives this class. It is
 * vtkPreciseMarchingCubes with a MaxTriangles setter that ParaView's
 * client-server layer can call: that layer wraps no setter taking an
 * unsigned 64-bit integer.
 */

#ifndef vtkPVPreciseMarchingCubes_h
#define vtkPVPreciseMarchingCubes_h

#include "vtkPreciseMCModule.h" // For export macro
#include "vtkPreciseMarchingCubes.h"

class VTKPRECISEMC_EXPORT vtkPVPreciseMarchingCubes : public vtkPreciseMarchingCubes
{
public:
  static vtkPVPreciseMarchingCubes* New();
  vtkTypeMacro(vtkPVPreciseMarchingCubes, vtkPreciseMarchingCubes);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  ///@{
  /**
   * MaxTriangles (see vtkPreciseMarchingCubes::SetMaxTriangles()) as a
   * signed integer; values below 1 mean no cap.
   */
  void SetMaxTrianglesSigned(vtkIdType count);
  vtkIdType GetMaxTrianglesSigned();
  ///@}

protected:
  vtkPVPreciseMarchingCubes() = default;
  ~vtkPVPreciseMarchingCubes() override = default;

  /**
   * In a distributed run, asks the other processes (the global controller)
   * whether they hold the whole volume too before contouring: where the
   * whole volume went to some of them only and the others got nothing (a
   * reader that reads on the first process only, as the legacy VTK reader
   * does), the first of its holders contours all of it instead of its
   * piece (see vtkPreciseMarchingCubes::WholeInputShare). Every process
   * of a ParaView pipeline executes it together; the exchange is skipped
   * for a composite input, whose blocks execute one by one.
   */
  int RequestData(vtkInformation*, vtkInformationVector**, vtkInformationVector*) override;

private:
  vtkPVPreciseMarchingCubes(const vtkPVPreciseMarchingCubes&) = delete;
  void operator=(const vtkPVPreciseMarchingCubes&) = delete;
};

#endif
