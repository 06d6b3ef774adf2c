/*=========================================================================

  Program:   PreciseMC
  Module:    vtkPVPreciseMarchingCubes.cxx

  Copyright (c) the PreciseMC authors
  All rights reserved.
  Licensed under the MIT or Apache-2.0 license, at your option.

     This software is distributed WITHOUT ANY WARRANTY; without even
     the implied warranty of MERCHANTABILITY or FITNESS FOR A PARTICULAR
     PURPOSE.

=========================================================================*/
#include "vtkPVPreciseMarchingCubes.h"

#include "vtkCommunicator.h"
#include "vtkImageData.h"
#include "vtkInformation.h"
#include "vtkInformationVector.h"
#include "vtkMultiProcessController.h"
#include "vtkObjectFactory.h"
#include "vtkStreamingDemandDrivenPipeline.h"

#include <algorithm>

vtkStandardNewMacro(vtkPVPreciseMarchingCubes);

//------------------------------------------------------------------------------
int vtkPVPreciseMarchingCubes::RequestData(
  vtkInformation* request, vtkInformationVector** inputVector, vtkInformationVector* outputVector)
{
  this->WholeInputShare = WHOLE_INPUT_AS_ASKED;
  vtkMultiProcessController* controller = vtkMultiProcessController::GetGlobalController();
  const int processes = controller ? controller->GetNumberOfProcesses() : 1;
  vtkInformation* inInfo = inputVector[0]->GetInformationObject(0);
  vtkImageData* input = vtkImageData::GetData(inputVector[0]);
  // Never for the blocks of a composite input, whose number may differ
  // between processes: the pipeline executes them one by one, each asked
  // for as the only piece.
  if (processes > 1 && this->HasContourExtent && this->ContourPieces == processes &&
    this->ContourPiece == controller->GetLocalProcessId() && inInfo && input &&
    inInfo->Has(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT()))
  {
    int whole[6];
    inInfo->Get(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT(), whole);
    int extent[6];
    input->GetExtent(extent);
    const bool empty = input->GetNumberOfPoints() == 0;
    // With no whole extent known (ContourWholeUnknown) what arrived is
    // taken for the whole volume.
    const bool holdsWhole =
      !empty && (this->ContourWholeUnknown || std::equal(extent, extent + 6, whole));
    const int rank = controller->GetLocalProcessId();
    // Sums of the holders and of the empty pieces; the first holder.
    int local[3] = { holdsWhole ? 1 : 0, empty ? 1 : 0, holdsWhole ? processes - rank : 0 };
    int global[3] = { 0, 0, 0 };
    controller->AllReduce(local, global, 2, vtkCommunicator::SUM_OP);
    controller->AllReduce(local + 2, global + 2, 1, vtkCommunicator::MAX_OP);
    // Without a whole extent the holders may hold one volume each (a
    // source that split it its own way): then the extents that arrived
    // differ, and each holder contours all of its own. Reduced on every
    // rank, whatever its ContourWholeUnknown (a rank's own flag: ranks
    // that disagreed made different numbers of collective calls and hung);
    // with a whole extent known the holders' extents are all the whole, so
    // `differ` stays false there.
    int lowest[6], highest[6];
    int lowestAll[6], highestAll[6];
    for (int i = 0; i < 6; ++i)
    {
      lowest[i] = holdsWhole ? extent[i] : VTK_INT_MAX;
      highest[i] = holdsWhole ? extent[i] : VTK_INT_MIN;
    }
    controller->AllReduce(lowest, lowestAll, 6, vtkCommunicator::MIN_OP);
    controller->AllReduce(highest, highestAll, 6, vtkCommunicator::MAX_OP);
    const bool differ = global[0] >= 1 && !std::equal(lowestAll, lowestAll + 6, highestAll);
    if (differ && holdsWhole)
    {
      this->WholeInputShare = WHOLE_INPUT_ALL;
    }
    else if (!differ && global[0] >= 1 && global[1] >= 1 && global[0] + global[1] == processes &&
      holdsWhole)
    {
      this->WholeInputShare =
        processes - global[2] == rank ? WHOLE_INPUT_ALL : WHOLE_INPUT_NONE;
    }
  }
  const int result = this->Superclass::RequestData(request, inputVector, outputVector);
  this->WholeInputShare = WHOLE_INPUT_AS_ASKED;
  return result;
}

//------------------------------------------------------------------------------
void vtkPVPreciseMarchingCubes::SetMaxTrianglesSigned(vtkIdType count)
{
  this->SetMaxTriangles(count > 0 ? static_cast<vtkTypeUInt64>(count) : 0);
}

//------------------------------------------------------------------------------
vtkIdType vtkPVPreciseMarchingCubes::GetMaxTrianglesSigned()
{
  const vtkTypeUInt64 count = this->GetMaxTriangles();
  return count > static_cast<vtkTypeUInt64>(VTK_ID_MAX) ? VTK_ID_MAX
                                                         : static_cast<vtkIdType>(count);
}

//------------------------------------------------------------------------------
void vtkPVPreciseMarchingCubes::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
}
