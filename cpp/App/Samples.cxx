// Built-in sample volumes: the features where the trilinear refinement of
// PreciseMC matters most, generated in code (no data files).
#include "Samples.h"

#include "vtkFloatArray.h"
#include "vtkImageData.h"
#include "vtkPointData.h"
#include "vtkUnsignedCharArray.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>

namespace pmcapp
{
namespace
{

const double Pi = 3.14159265358979323846;

vtkSmartPointer<vtkImageData> NewVolume(int nx, int ny, int nz, double spacing, double origin)
{
  auto image = vtkSmartPointer<vtkImageData>::New();
  image->SetDimensions(nx, ny, nz);
  image->SetSpacing(spacing, spacing, spacing);
  image->SetOrigin(origin, origin, origin);
  return image;
}

// Distance from p to the segment [a, b].
double SegmentDistance(const double p[3], const double a[3], const double b[3])
{
  double ab[3] = { b[0] - a[0], b[1] - a[1], b[2] - a[2] };
  double ap[3] = { p[0] - a[0], p[1] - a[1], p[2] - a[2] };
  double len2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
  double t = len2 > 0.0 ? (ap[0] * ab[0] + ap[1] * ab[1] + ap[2] * ab[2]) / len2 : 0.0;
  t = std::min(1.0, std::max(0.0, t));
  double d[3] = { ap[0] - t * ab[0], ap[1] - t * ab[1], ap[2] - t * ab[2] };
  return std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
}

// A trefoil knot of tube radius below one cell: Marching Cubes breaks it
// into beads and slabs, the refined surface is a round tube.
Sample MakeTube()
{
  const int nx = 48, ny = 48, nz = 20;
  const double radius = 0.55; // of the Gaussian profile, in cells
  const int segments = 720;
  auto image = NewVolume(nx, ny, nz, 1.0, 0.0);

  // The knot: (sin t + 2 sin 2t, cos t - 2 cos 2t, -sin 3t), scaled into
  // the grid and off the sample lattice.
  std::vector<double> curve(3 * (segments + 1));
  for (int i = 0; i <= segments; ++i)
  {
    double t = 2.0 * Pi * i / segments;
    curve[3 * i + 0] = 23.37 + 7.1 * (std::sin(t) + 2.0 * std::sin(2.0 * t));
    curve[3 * i + 1] = 24.81 + 7.1 * (std::cos(t) - 2.0 * std::cos(2.0 * t));
    curve[3 * i + 2] = 9.43 - 5.3 * std::sin(3.0 * t);
  }

  auto values = vtkSmartPointer<vtkUnsignedCharArray>::New();
  values->SetName("density");
  values->SetNumberOfTuples(static_cast<vtkIdType>(nx) * ny * nz);
  unsigned char* out = values->GetPointer(0);
  for (int k = 0; k < nz; ++k)
  {
    for (int j = 0; j < ny; ++j)
    {
      for (int i = 0; i < nx; ++i)
      {
        double p[3] = { double(i), double(j), double(k) };
        double d = 1e30;
        for (int s = 0; s < segments; ++s)
        {
          d = std::min(d, SegmentDistance(p, &curve[3 * s], &curve[3 * s + 3]));
        }
        double v = 255.0 * std::exp(-(d / radius) * (d / radius));
        *out++ = static_cast<unsigned char>(std::lround(std::min(255.0, v)));
      }
    }
  }
  image->GetPointData()->SetScalars(values);
  return Sample{ "tube", "a trefoil tube thinner than a cell (48x48x20, uint8)", 50.5, image };
}

// Minimal linear congruential generator, for fixed pseudo-random atoms.
struct Lcg
{
  uint64_t State;
  double Next() // uniform in [0, 1)
  {
    this->State = this->State * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(this->State >> 11) * (1.0 / 9007199254740992.0);
  }
};

// A chain of Gaussian atoms, like a low-resolution electron-density map:
// bonds thinner than the grid spacing form necks and saddles.
Sample MakeAtoms()
{
  const int n = 40;
  const int atoms = 48;
  const double bond = 2.6;  // cells
  const double sigma = 0.9; // cells
  auto image = NewVolume(n, n, n, 1.0, 0.0);

  Lcg rng{ 20240607ULL };
  std::vector<double> pos;
  double p[3] = { 19.3, 20.1, 19.7 };
  double dir[3] = { 1.0, 0.0, 0.0 };
  for (int a = 0; a < atoms; ++a)
  {
    pos.insert(pos.end(), p, p + 3);
    // Next direction: the previous one bent by a random angle (a chain,
    // not a cloud), kept inside the box.
    for (int attempt = 0; attempt < 64; ++attempt)
    {
      double u = 2.0 * rng.Next() - 1.0;
      double phi = 2.0 * Pi * rng.Next();
      double s = std::sqrt(1.0 - u * u);
      double r[3] = { s * std::cos(phi), s * std::sin(phi), u };
      double d[3] = { dir[0] + 1.1 * r[0], dir[1] + 1.1 * r[1], dir[2] + 1.1 * r[2] };
      double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      if (len < 1e-6)
      {
        continue;
      }
      double q[3];
      for (int c = 0; c < 3; ++c)
      {
        d[c] /= len;
        q[c] = p[c] + bond * d[c];
      }
      bool inside = true;
      for (int c = 0; c < 3; ++c)
      {
        inside = inside && q[c] > 5.0 && q[c] < n - 6.0;
      }
      bool clash = false;
      for (size_t b = 0; b + 3 < pos.size() && !clash; b += 3)
      {
        double e[3] = { q[0] - pos[b], q[1] - pos[b + 1], q[2] - pos[b + 2] };
        clash = e[0] * e[0] + e[1] * e[1] + e[2] * e[2] < 0.8 * bond * bond;
      }
      if (inside && (!clash || attempt == 63))
      {
        for (int c = 0; c < 3; ++c)
        {
          dir[c] = d[c];
          p[c] = q[c];
        }
        break;
      }
    }
  }

  auto values = vtkSmartPointer<vtkFloatArray>::New();
  values->SetName("density");
  values->SetNumberOfTuples(static_cast<vtkIdType>(n) * n * n);
  float* out = values->GetPointer(0);
  for (int k = 0; k < n; ++k)
  {
    for (int j = 0; j < n; ++j)
    {
      for (int i = 0; i < n; ++i)
      {
        double v = 0.0;
        for (size_t b = 0; b < pos.size(); b += 3)
        {
          double dx = i - pos[b], dy = j - pos[b + 1], dz = k - pos[b + 2];
          double r2 = dx * dx + dy * dy + dz * dz;
          if (r2 < 36.0)
          {
            v += 200.0 * std::exp(-r2 / (2.0 * sigma * sigma));
          }
        }
        *out++ = static_cast<float>(std::min(255.0, v));
      }
    }
  }
  image->GetPointData()->SetScalars(values);
  return Sample{ "atoms", "a chain of 48 Gaussian atoms, electron-density-like (40^3, float)",
    50.5, image };
}

// The Marschner-Lobb test signal at 41^3 on [-1, 1]^3.
Sample MakeMarschnerLobb()
{
  const int n = 41;
  const double fM = 6.0, alpha = 0.25;
  const double h = 2.0 / (n - 1);
  auto image = NewVolume(n, n, n, h, -1.0);
  auto values = vtkSmartPointer<vtkFloatArray>::New();
  values->SetName("rho");
  values->SetNumberOfTuples(static_cast<vtkIdType>(n) * n * n);
  float* out = values->GetPointer(0);
  for (int k = 0; k < n; ++k)
  {
    for (int j = 0; j < n; ++j)
    {
      for (int i = 0; i < n; ++i)
      {
        double x = -1.0 + h * i, y = -1.0 + h * j, z = -1.0 + h * k;
        double r = std::sqrt(x * x + y * y);
        double rho = (1.0 - std::sin(Pi * z / 2.0) +
                       alpha * (1.0 + std::cos(2.0 * Pi * fM * std::cos(Pi * r / 2.0)))) /
          (2.0 * (1.0 + alpha));
        *out++ = static_cast<float>(rho);
      }
    }
  }
  image->GetPointData()->SetScalars(values);
  return Sample{ "ml", "the Marschner-Lobb signal (41^3 on [-1,1]^3, float)", 0.5, image };
}

}

std::vector<std::string> SampleNames()
{
  return { "tube", "atoms", "ml" };
}

Sample MakeSample(const std::string& name)
{
  if (name == "tube")
  {
    return MakeTube();
  }
  if (name == "atoms")
  {
    return MakeAtoms();
  }
  if (name == "ml")
  {
    return MakeMarschnerLobb();
  }
  throw std::invalid_argument("unknown sample '" + name + "'");
}

}
