// Runs one VXA file in the VoxCAD fork shipped with evosoro (evosoro/_voxcad_land_water, commit
// b95ec95), for bench/voxcad_reference.py. Links the fork's libvoxelyze.0.9.a.
//
// Usage: voxcad-driver FILE.vxa [--every K] [--frames N] [--voxels all|first-last|i,j,...]
//                                [--coarse M] [--fitness OUT.xml]
//
// The simulation is set up and stepped exactly as voxelyzeMain/main.cpp does it (LoadVXAFile,
// Import, UpdateCurTemp(0), then TimeStep / Time += dt / UpdateCurTemp(Time) until
// StopConditionMet()), without main.cpp's console output and without its convex-hull and
// shape-complexity measurements (they shell out to qhull and python and sleep a second each;
// they do not touch the physics). The robot volume at the start and the end is computed with
// the fork's own mesh code, as main.cpp does.
//
// Output, JSON lines on stdout:
//   {"kind": "header", ...}   voxel count, bond count, dt (= DtFrac * OptimalDt), the lattice
//                             indices [i, j, k] of every voxel in the fork's voxel order (VoxArray)
//   {"kind": "frame", ...}    every K steps for the first N steps (steps 0, K, 2K, ... <= N):
//                             step, t, centre of mass, positions of the chosen voxels
//   {"kind": "com", ...}      every M steps over the whole run (--coarse M): step, t, centre of mass
//   {"kind": "result", ...}   steps, simulated time, wall seconds of the stepping loop, the
//                             initial and final centre of mass used for the fitness, and the
//                             fitness-file values in double precision
// With --fitness the fork's own SaveResultFile writes its fitness XML there as well.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <string>
#include <vector>

#include "VX_Environment.h"
#include "VX_MeshUtil.h"
#include "VX_Object.h"
#include "VX_Sim.h"
#include "VX_SimGA.h"

static void vec(std::ostringstream& os, const Vec3D<>& v) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "[%.10g, %.10g, %.10g]", v.x, v.y, v.z);
  os << buf;
}

int main(int argc, char* argv[]) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s FILE.vxa [--every K] [--frames N] [--voxels SPEC] [--fitness OUT]\n", argv[0]);
    return 2;
  }
  std::string file = argv[1], voxspec = "first-last", fitness;
  long every = 0, frames = -1, coarse = 0;
  for (int a = 2; a + 1 < argc; a += 2) {
    if (!std::strcmp(argv[a], "--every")) every = std::atol(argv[a + 1]);
    else if (!std::strcmp(argv[a], "--frames")) frames = std::atol(argv[a + 1]);
    else if (!std::strcmp(argv[a], "--voxels")) voxspec = argv[a + 1];
    else if (!std::strcmp(argv[a], "--coarse")) coarse = std::atol(argv[a + 1]);
    else if (!std::strcmp(argv[a], "--fitness")) fitness = argv[a + 1];
    else { std::fprintf(stderr, "unknown option %s\n", argv[a]); return 2; }
  }

  CVX_Object object;
  CVX_Environment environment;
  CVX_SimGA sim;
  CVX_MeshUtil mesh;
  sim.pEnv = &environment;
  environment.pObj = &object;
  sim.setInternalMesh(&mesh);
  std::string message;
  if (!sim.LoadVXAFile(file, &message)) { std::fprintf(stderr, "cannot load %s\n", file.c_str()); return 2; }
  if (!sim.Import(&environment, 0, &message)) { std::fprintf(stderr, "import failed: %s\n", message.c_str()); return 2; }
  double time = 0.0;
  sim.pEnv->UpdateCurTemp(time);
  mesh.initializeDeformableMesh(&sim);
  mesh.computeAndStoreRobotVolumeStart();

  const int n = sim.NumVox();
  std::vector<int> chosen;
  if (voxspec == "all") {
    for (int v = 0; v < n; ++v) chosen.push_back(v);
  } else if (voxspec == "first-last") {
    chosen.push_back(0);
    if (n > 1) chosen.push_back(n - 1);
  } else {
    std::stringstream ss(voxspec);
    std::string item;
    while (std::getline(ss, item, ',')) {
      int v = std::atoi(item.c_str());
      if (v >= 0 && v < n) chosen.push_back(v);
    }
  }

  {
    std::ostringstream os;
    char buf[256];
    std::snprintf(buf, sizeof buf,
                  "{\"kind\": \"header\", \"voxels\": %d, \"bonds\": %d, \"surface_voxels\": %d, "
                  "\"lattice_dim\": %.10g, \"optimal_dt\": %.12g, \"dt_frac\": %.12g, \"dt\": %.12g, ",
                  n, sim.NumBond(), sim.NumSurfVoxels(), sim.LocalVXC.GetLatticeDim(), sim.OptimalDt,
                  sim.DtFrac, sim.DtFrac * sim.OptimalDt);
    os << buf << "\"ijk\": [";
    for (int v = 0; v < n; ++v) {
      int x, y, z;
      sim.LocalVXC.GetXYZNom(&x, &y, &z, sim.StoXIndexMap[v]);
      os << (v ? ", " : "") << "[" << x << ", " << y << ", " << z << "]";
    }
    os << "], \"tracked\": [";
    for (size_t c = 0; c < chosen.size(); ++c) os << (c ? ", " : "") << chosen[c];
    os << "]}";
    std::puts(os.str().c_str());
  }

  long step = 0;
  auto frame = [&]() {
    std::ostringstream os;
    char buf[96];
    std::snprintf(buf, sizeof buf, "{\"kind\": \"frame\", \"step\": %ld, \"t\": %.12g, \"com\": ", step, sim.CurTime);
    os << buf;
    vec(os, sim.GetCM());
    os << ", \"pos\": [";
    for (size_t c = 0; c < chosen.size(); ++c) {
      if (c) os << ", ";
      vec(os, sim.VoxArray[chosen[c]].GetCurPos());
    }
    os << "]}";
    std::puts(os.str().c_str());
  };

  auto com = [&]() {
    std::ostringstream os;
    char buf[96];
    std::snprintf(buf, sizeof buf, "{\"kind\": \"com\", \"step\": %ld, \"t\": %.12g, \"com\": ", step, sim.CurTime);
    os << buf;
    vec(os, sim.GetCM());
    os << "}";
    std::puts(os.str().c_str());
  };

  bool stable = true;
  auto start = std::chrono::steady_clock::now();
  while (!sim.StopConditionMet()) {
    if (every > 0 && step % every == 0 && step <= frames) frame();
    if (coarse > 0 && step % coarse == 0) com();
    if (!sim.TimeStep(&message)) { stable = false; break; }
    step += 1;
    time += sim.dt;
    sim.pEnv->UpdateCurTemp(time);
  }
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (every > 0 && step % every == 0 && step <= frames) frame();
  if (coarse > 0) com();

  mesh.computeAndStoreRobotVolumeEnd();
  if (!fitness.empty()) sim.SaveResultFile(fitness);

  // The fitness-file values, as CVX_SimGA::WriteResultFile computes them (there in float).
  Vec3D<> d = (sim.SS.CurCM - sim.IniCM) / sim.LocalVXC.GetLatticeDim();
  std::ostringstream os;
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "{\"kind\": \"result\", \"stable\": %s, \"steps\": %ld, \"t\": %.12g, \"dt\": %.12g, "
                "\"seconds\": %.6f, \"voxels\": %d, \"normAbsoluteDisplacement\": %.10g, \"normDistX\": %.10g, "
                "\"normDistY\": %.10g, \"normDistZ\": %.10g, \"RobotVolumeStart\": %.10g, \"RobotVolumeEnd\": %.10g, ",
                stable ? "true" : "false", step, sim.CurTime, sim.dt, seconds, n, d.Length(), d.x, d.y, d.z,
                mesh.getRobotVolumeStart(), mesh.getRobotVolumeEnd());
  os << buf << "\"ini_cm\": ";
  vec(os, sim.IniCM);
  os << ", \"final_cm\": ";
  vec(os, sim.SS.CurCM);
  os << "}";
  std::puts(os.str().c_str());
  return stable ? 0 : 1;
}
