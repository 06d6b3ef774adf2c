/*=========================================================================

  Program:   PreciseMC
  Module:    TestCaseTable.cxx

  Compares the Marching Cubes case table of the Rust core
  (src/tables/vtk_cases.rs, parsed at run time) entry by entry with
  vtkMarchingCubesTriangleCases::GetCases().

=========================================================================*/
#include "vtkMarchingCubesTriangleCases.h"

#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

int main(int argc, char* argv[])
{
  if (argc < 2)
  {
    std::cerr << "usage: " << argv[0] << " <path to src/tables/vtk_cases.rs>\n";
    return EXIT_FAILURE;
  }
  std::ifstream in(argv[1]);
  if (!in)
  {
    std::cerr << "cannot open " << argv[1] << "\n";
    return EXIT_FAILURE;
  }

  // Rows look like `    [0, 3, 8, -1, ...], // 1` inside the array
  // `VTK_TRIANGLE_CASES`; read the numbers between the brackets.
  std::vector<std::vector<int>> rows;
  std::string line;
  bool inTable = false;
  while (std::getline(in, line))
  {
    if (!inTable)
    {
      if (line.find("VTK_TRIANGLE_CASES") != std::string::npos &&
        line.find('=') != std::string::npos)
      {
        inTable = true;
      }
      continue;
    }
    std::string code = line.substr(0, line.find("//"));
    if (code.find("];") != std::string::npos && code.find('[') == std::string::npos)
    {
      break;
    }
    size_t open = code.find('[');
    size_t close = code.find(']');
    if (open == std::string::npos || close == std::string::npos || close < open)
    {
      continue;
    }
    std::string body = code.substr(open + 1, close - open - 1);
    for (char& ch : body)
    {
      if (ch == ',')
      {
        ch = ' ';
      }
    }
    std::istringstream numbers(body);
    std::vector<int> row;
    int v;
    while (numbers >> v)
    {
      row.push_back(v);
    }
    rows.push_back(row);
  }

  if (rows.size() != 256)
  {
    std::cerr << "expected 256 cases in " << argv[1] << ", found " << rows.size() << "\n";
    return EXIT_FAILURE;
  }

  vtkMarchingCubesTriangleCases* cases = vtkMarchingCubesTriangleCases::GetCases();
  int errors = 0;
  int triangles = 0;
  for (int c = 0; c < 256; ++c)
  {
    const std::vector<int>& row = rows[c];
    if (row.size() != 16)
    {
      std::cerr << "case " << c << ": " << row.size() << " entries, expected 16\n";
      ++errors;
      continue;
    }
    const EDGE_LIST* edges = cases[c].edges;
    // Compare up to and including VTK's terminating -1; everything after it
    // must be -1 in the Rust table.
    bool ended = false;
    for (int e = 0; e < 16; ++e)
    {
      if (!ended)
      {
        if (row[e] != edges[e])
        {
          std::cerr << "case " << c << " entry " << e << ": Rust " << row[e] << ", VTK "
                    << edges[e] << "\n";
          ++errors;
          break;
        }
        if (edges[e] < 0)
        {
          ended = true;
        }
        else if (e % 3 == 0)
        {
          ++triangles;
        }
      }
      else if (row[e] != -1)
      {
        std::cerr << "case " << c << " entry " << e << ": expected -1 after the end, got "
                  << row[e] << "\n";
        ++errors;
        break;
      }
    }
  }
  if (errors)
  {
    std::cerr << errors << " case(s) differ\n";
    return EXIT_FAILURE;
  }
  std::cout << "256 cases, " << triangles << " triangles: the Rust table equals VTK's\n";
  return EXIT_SUCCESS;
}
