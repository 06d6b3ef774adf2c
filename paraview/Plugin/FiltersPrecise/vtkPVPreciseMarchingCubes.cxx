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

#include "vtkObjectFactory.h"

vtkStandardNewMacro(vtkPVPreciseMarchingCubes);

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
