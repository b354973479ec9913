// hemm-shape3d-replay: fits the 3D shape completion again to the cells of
// logged rebuilds (hemm-operator --shape-log: DIR/cells_<build>.f32), in
// the order given, each with the previous one's primitives for temporal
// coherence as the live voxmap does. Offline there is no free-space
// record: no fit is refused for closing space seen free, so this shows what
// the fit alone accepts. Prints primitives.csv's columns (build = the
// argument's index) to stdout.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "common/mapping/shape_completion3d.h"

int main(int argc, char** argv) {
  CLI::App app{"fit the 3D shape completion again to logged rebuilds' cells (hemm-operator --shape-log)"};
  std::vector<std::string> files;
  app.add_option("cells", files, "DIR/cells_<build>.f32 files, in order")->required()->check(CLI::ExistingFile);
  CLI11_PARSE(app, argc, argv);
  const hemm::mapping::Shape3dParams params;
  hemm::mapping::Shape3dModel model;
  std::printf("build,cells,objects,support_nx,support_ny,support_nz,support_d,%s\n",
              hemm::mapping::primitive_csv_header().c_str());
  for (std::size_t i = 0; i < files.size(); ++i) {
    std::ifstream in(files[i], std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::vector<hemm::mapping::CellSample3> cells;
    if (const std::string e = hemm::mapping::cells_from_bytes(bytes, &cells); !e.empty()) {
      std::fprintf(stderr, "hemm-shape3d-replay: %s: %s\n", files[i].c_str(), e.c_str());
      return 2;
    }
    hemm::mapping::complete_shapes_3d(params, cells, {}, model);
    for (const auto& q : model.primitives)
      std::printf("%zu,%zu,%zu,%.4f,%.4f,%.4f,%.5f,%s\n", i, cells.size(), model.objects, model.support[0],
                  model.support[1], model.support[2], model.support[3], hemm::mapping::primitive_csv_row(q).c_str());
  }
  return 0;
}
