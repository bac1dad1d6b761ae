// Generates tests/data/vdbio_foreign.vdb: grids of the types and transforms
// baker itself never writes, as other tools may. Not part of the build:
//   g++ -std=c++17 -O1 vdbio_foreign.cpp -lopenvdb -ltbb -lImath-3_1 -o /tmp/gen && /tmp/gen vdbio_foreign.vdb
// Every grid holds the 4x4x4 index box [0,3]^3 (tests/test_vdbio.c repeats this):
//   dens_d   double  1 + i + 10j + 100k, linear: voxel 0.5, index (0,0,0) at (1,2,3)
//   vel_d    Vec3d   (i + 0.5, j + 0.5, k + 0.5), same transform
//   count_i  int32   i + j + k, same transform
//   rotated  float   1 + i + 10j + 100k, affine: scale (0.5, 1, 2), then 90 degrees
//                    about z, then translate (1, 2, 3): world = (1 - j, 2 + 0.5 i, 3 + 2k)
//   frustum  float   1, frustum transform
#include <openvdb/openvdb.h>
#include <openvdb/math/Maps.h>

using namespace openvdb;

template <typename GridT, typename F>
static typename GridT::Ptr make(const char *name, math::Transform::Ptr xf, F f) {
  typename GridT::Ptr g = GridT::create();
  auto acc = g->getAccessor();
  for (int k = 0; k < 4; k++)
    for (int j = 0; j < 4; j++)
      for (int i = 0; i < 4; i++) acc.setValue(Coord(i, j, k), f(i, j, k));
  g->setName(name);
  g->setTransform(xf);
  return g;
}

int main(int argc, char **argv) {
  if (argc != 2) return 2;
  initialize();
  math::Transform::Ptr lin = math::Transform::createLinearTransform(0.5);
  lin->postTranslate(Vec3d(1, 2, 3));
  math::Transform::Ptr rot = math::Transform::createLinearTransform(1.0);
  rot->preScale(Vec3d(0.5, 1.0, 2.0));
  rot->postRotate(M_PI / 2, math::Z_AXIS);
  rot->postTranslate(Vec3d(1, 2, 3));
  math::Transform::Ptr fru = math::Transform::createFrustumTransform(
      BBoxd(Vec3d(0, 0, 0), Vec3d(4, 4, 4)), 0.5, 2.0, 0.5);
  GridPtrVec grids;
  grids.push_back(make<DoubleGrid>("dens_d", lin->copy(),
                                   [](int i, int j, int k) { return 1.0 + i + 10 * j + 100 * k; }));
  grids.push_back(make<Vec3DGrid>("vel_d", lin->copy(), [](int i, int j, int k) {
    return Vec3d(i + 0.5, j + 0.5, k + 0.5);
  }));
  grids.push_back(make<Int32Grid>("count_i", lin->copy(), [](int i, int j, int k) { return i + j + k; }));
  grids.push_back(make<FloatGrid>("rotated", rot,
                                  [](int i, int j, int k) { return 1.0f + i + 10 * j + 100 * k; }));
  grids.push_back(make<FloatGrid>("frustum", fru, [](int, int, int) { return 1.0f; }));
  io::File file(argv[1]);
  file.setCompression(io::COMPRESS_ZIP | io::COMPRESS_ACTIVE_MASK);
  file.write(grids);
  file.close();
  return 0;
}
