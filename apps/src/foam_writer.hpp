// OpenFOAM field files: a cell field as an ASCII volScalarField (e.g. 0/voidfraction) that
// a solver or ParaView's OpenFOAM reader loads next to the case's polyMesh.
#pragma once

#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace vfe::apps {

/// A boundary patch whose field entry must be of its own (constraint) type: empty, wedge,
/// symmetryPlane, symmetry, cyclic, cyclicAMI, cyclicACMI, cyclicSlip.
struct FoamPatch {
  std::string name;
  std::string type;
};

/// The constraint patches of the polyMesh folder's `boundary` file (plain or .gz). Every
/// other patch is covered by a zeroGradient regex entry. Best effort: an unreadable or
/// unusual file yields an empty list (then all patches get zeroGradient).
std::vector<FoamPatch> read_constraint_patches(const std::filesystem::path& polymesh_folder);

/// Writes an ASCII volScalarField named `object` (dimensionless, one value per cell in the
/// mesh's cell order, internalField nonuniform List<scalar>; boundaryField: ".*" as
/// zeroGradient plus each constraint patch with its own type). `location` is the time
/// folder's name ("0"); note goes into the header (e.g. the method's options). Creates the
/// folder; throws std::runtime_error when the file cannot be written.
void write_foam_scalar_field(const std::filesystem::path& file, const std::string& object,
                             const std::string& location, std::span<const double> values,
                             const std::vector<FoamPatch>& constraint_patches = {},
                             const std::string& note = "");

/// The same as an ASCII volVectorField: values holds x, y, z per cell; dimensions in
/// OpenFOAM's notation (a velocity is "[0 1 -1 0 0 0 0]").
void write_foam_vector_field(const std::filesystem::path& file, const std::string& object,
                             const std::string& location, std::span<const double> values,
                             const std::string& dimensions, const std::vector<FoamPatch>& constraint_patches = {},
                             const std::string& note = "");

}  // namespace vfe::apps
