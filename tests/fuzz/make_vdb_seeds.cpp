// Generates the seed corpus of fuzz_vdb (tests/fuzz/corpus/fuzz_vdb/): small
// files in each compression, with a float fog grid and a Vec3f grid over a
// 4x4x4 box, plus one with half floats. Not part of the build:
//   g++ -std=c++17 -O1 make_vdb_seeds.cpp -lopenvdb -ltbb -lImath-3_1 -o /tmp/gen && /tmp/gen DIR
#include <openvdb/openvdb.h>

#include <string>

using namespace openvdb;

static GridPtrVec grids(bool half) {
  FloatGrid::Ptr f = FloatGrid::create();
  Vec3SGrid::Ptr v = Vec3SGrid::create();
  auto fa = f->getAccessor();
  auto va = v->getAccessor();
  for (int k = 0; k < 4; k++)
    for (int j = 0; j < 4; j++)
      for (int i = 0; i < 4; i++) {
        fa.setValue(Coord(i, j, k), 1.0f + i + 10 * j + 100 * k);
        va.setValue(Coord(i, j, k), Vec3s(i * 0.5f, j * 0.25f, k + 1.0f));
      }
  f->setName("density");
  f->setGridClass(GRID_FOG_VOLUME);
  v->setName("radiance");
  f->setTransform(math::Transform::createLinearTransform(0.25));
  v->setTransform(math::Transform::createLinearTransform(0.25));
  f->setSaveFloatAsHalf(half);
  v->setSaveFloatAsHalf(half);
  return {f, v};
}

static void write(const std::string &path, uint32_t compression, bool half) {
  io::File file(path);
  file.setCompression(compression);
  MetaMap meta;
  meta.insertMeta("creator", StringMetadata("fuzz seed"));
  file.write(grids(half), meta);
  file.close();
}

int main(int argc, char **argv) {
  if (argc != 2) return 2;
  initialize();
  std::string dir = argv[1];
  write(dir + "/mask_only.vdb", io::COMPRESS_ACTIVE_MASK, false); // no codec
  write(dir + "/zip.vdb", io::COMPRESS_ZIP | io::COMPRESS_ACTIVE_MASK, false);
  write(dir + "/blosc.vdb", io::COMPRESS_BLOSC | io::COMPRESS_ACTIVE_MASK, false);
  write(dir + "/half_zip.vdb", io::COMPRESS_ZIP | io::COMPRESS_ACTIVE_MASK, true);
  return 0;
}
