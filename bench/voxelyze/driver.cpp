// Times Voxelyze (jonhiller/Voxelyze) on one scene read from stdin, for bench/voxelyze_paired.py.
//
// Input (whitespace separated):
//   voxel_size steps collisions amplitude poisson gravity_g
//   damping_bond damping_global damping_collision friction_static friction_kinetic
//   n_materials, then per material: youngs_modulus density
//   n_voxels, then per voxel: i j k material active phase frequency
// Output: one JSON line with the voxel count, steps, wall seconds and the centre of mass.
//
// Actuation as in VoxCAD: each active voxel's temperature is set every step to
// sin(2 pi f t + phase) with the material's thermal expansion coefficient = amplitude, so its
// rest size is s (1 + amplitude sin(2 pi f t + phase)). The step is Voxelyze's own
// recommendedTimeStep(), computed once before timing (doTimeStep() without an argument would
// recompute it every step, which would only slow Voxelyze down).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <vector>

#include "Voxelyze.h"

int main() {
  double size, amplitude, poisson, gravity, zb, zg, zc, mus, muk;
  long steps;
  int collisions, n_materials, n_voxels;
  std::cin >> size >> steps >> collisions >> amplitude >> poisson >> gravity;
  std::cin >> zb >> zg >> zc >> mus >> muk >> n_materials;
  if (!std::cin) return 2;
  CVoxelyze vx(size);
  std::vector<CVX_Material*> materials;
  for (int m = 0; m < n_materials; ++m) {
    double e, rho;
    std::cin >> e >> rho;
    CVX_Material* mat = vx.addMaterial(e, rho);
    mat->setPoissonsRatio(poisson);
    mat->setInternalDamping(zb);
    mat->setGlobalDamping(zg);
    mat->setCollisionDamping(zc);
    mat->setStaticFriction(mus);
    mat->setKineticFriction(muk);
    mat->setCte(amplitude);
    materials.push_back(mat);
  }
  std::cin >> n_voxels;
  std::vector<CVX_Voxel*> active;
  std::vector<double> phase, frequency;
  for (int v = 0; v < n_voxels; ++v) {
    int i, j, k, m, a;
    double ph, f;
    std::cin >> i >> j >> k >> m >> a >> ph >> f;
    CVX_Voxel* voxel = vx.setVoxel(materials[m], i, j, k);
    if (a) {
      active.push_back(voxel);
      phase.push_back(ph);
      frequency.push_back(f);
    }
  }
  if (!std::cin) return 2;
  vx.enableFloor(true);
  vx.setGravity(gravity);
  vx.enableCollisions(collisions != 0);
  const double dt = vx.recommendedTimeStep();
  const double two_pi = 6.283185307179586;
  double t = 0.0;
  auto start = std::chrono::steady_clock::now();
  for (long s = 0; s < steps; ++s) {
    for (size_t a = 0; a < active.size(); ++a)
      active[a]->setTemperature(std::sin(two_pi * frequency[a] * t + phase[a]));
    if (!vx.doTimeStep(dt)) {
      std::printf("{\"stable\": false, \"steps\": %ld}\n", s);
      return 1;
    }
    t += dt;
  }
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  double cx = 0, cy = 0, cz = 0, mass = 0;
  for (int v = 0; v < vx.voxelCount(); ++v) {
    CVX_Voxel* voxel = vx.voxel(v);
    Vec3D<double> p = voxel->position();
    double m = voxel->material()->mass();
    cx += m * p.x; cy += m * p.y; cz += m * p.z; mass += m;
  }
  std::printf("{\"stable\": true, \"voxels\": %d, \"steps\": %ld, \"dt\": %.9g, \"seconds\": %.6f, "
              "\"com\": [%.9g, %.9g, %.9g]}\n", vx.voxelCount(), steps, dt, seconds,
              cx / mass, cy / mass, cz / mass);
  return 0;
}
