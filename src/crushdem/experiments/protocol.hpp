// Controllers acting on a Simulation, and sample preparation (docs/model.md 4.1).
//
// Nothing here subclasses the engine: a controller is called between steps, every
// `check_interval` steps, reads the state and changes wall modes, targets or the friction
// coefficient. The test stages are controllers of the same kind (experiments/stages.hpp).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "crushdem/core/params.hpp"
#include "crushdem/experiments/measurements.hpp"
#include "crushdem/integrate/simulation.hpp"
#include "crushdem/particles/grading.hpp"
#include "crushdem/walls/body_config.hpp"

namespace crushdem {

// ---------------------------------------------------------------------------------------------
// Sample preparation
// ---------------------------------------------------------------------------------------------

/// A cube of grains drawn from a grading curve, or a cylinder in a chamber (docs/chamber.md),
/// compacted by servo walls to `stress` with a preparation friction lowered step by step until
/// the void ratio reaches `void_ratio`; the material friction is then restored and the sample
/// brought to equilibrium.
enum class SampleShape { Cube, Cylinder };
inline constexpr std::array<Named<SampleShape>, 2> kSampleShapeNames = {
    {{SampleShape::Cube, "cube"}, {SampleShape::Cylinder, "cylinder"}}};

/// How the loose cloud is brought together (docs/chamber.md, "A chamber sample"): swept by the
/// servo walls, or contracted evenly with them (each grain given the walls' homogeneous strain
/// rate as its velocity while the cloud is loose) until the walls carry `affine_release` of the
/// target stress.
enum class Compaction { Walls, Affine };
inline constexpr std::array<Named<Compaction>, 2> kCompactionNames = {
    {{Compaction::Walls, "walls"}, {Compaction::Affine, "affine"}}};

struct SampleConfig {
  GradingCurve grading = GradingCurve::ne34();
  SampleShape shape = SampleShape::Cube;
  double side = 0.0;             // cube side, or cylinder diameter, at the target void ratio [m]
                                 // (0: 4 mm unless count)
  double height_ratio = 1.0;     // cylinder: height / diameter [-]
  double sector = 360.0;         // cylinder: 360, or 180 / 90 between symmetry planes [deg]
  std::uint64_t count = 0;       // approximate number of grains (sets the side) instead of side
  double void_ratio = 0.65;      // target e [-] (STUDY)
  double tolerance = 0.005;      // accepted |e - void_ratio| [-]
  double stress = 100e3;         // isotropic stress of the prepared sample [Pa] (docs/model.md 4.1)
  std::uint64_t seed = 1;        // grain sizes and positions
  double friction_start = 0.5;   // preparation friction to start from [-]
  double friction_factor = 0.6;  // each lowering multiplies it by this [-]
  double placement_fraction = 0.3;  // solid fraction of the initial loose cloud [-]
  double max_speed = 0.3;           // wall speed limit during preparation [m/s]
  // How the loose cloud is compacted, and (affine) the fraction of `stress` on the walls at
  // which the grains stop following them (CHOICE).
  Compaction compaction = Compaction::Walls;
  double affine_release = 0.1;          // [-]
  double unbalanced = 5e-3;             // equilibrium: unbalanced-force ratio below this [-]
  double stress_tolerance = 0.01;       // equilibrium: every wall within this of `stress` [-]
  std::uint64_t check_interval = 1000;  // steps between checks
  std::uint64_t max_steps = 50000000;   // give up (error) after this many steps
  void validate(const SimulationConfig& sim) const;  // keys "sample.<key>"
  double cube_side() const;  // the side (a cube) or diameter (a cylinder) at the target e
  double height() const;     // the height at the target void ratio: the side, or the cylinder's
  /// The fraction of the circle a cylinder fills (sector / 360); 1 for a cube.
  double sector_fraction() const { return shape == SampleShape::Cylinder ? sector / 360.0 : 1.0; }
};

/// The scalar keys of [sample] (core/params.hpp); the grading is its own sub-table.
const ParamTable<SampleConfig>& sample_params();

// ---------------------------------------------------------------------------------------------
// Controllers
// ---------------------------------------------------------------------------------------------

/// Inertial number I = eps_dot d50 sqrt(rho / p) (docs/model.md 1.4), from the wall velocities
/// (largest strain rate of the three axes) and the mean wall stress; NaN when p <= 0.
double inertial_number(const Walls& w, double d50, double density);

/// Gives every grain the velocity of the sample walls' homogeneous deformation at its place
/// (along each axis, linear between the two walls; in a chamber, radial about the axis in
/// proportion to the radius) and no spin: the cloud contracts or expands with its walls.
void follow_walls(Simulation& sim);

/// Every controller: begin() once, then update() after every steps_to_check() steps until it
/// returns true. It may change walls and friction; it never steps the simulation itself.
class Controller {
 public:
  virtual ~Controller() = default;
  virtual void begin(Simulation& sim) = 0;
  virtual bool update(Simulation& sim) = 0;
  virtual std::uint64_t steps_to_check(Simulation& sim) = 0;
  /// Whether the next update() reads or changes the grains (positions, velocities, forces,
  /// crack lengths) rather than only the walls, the clock, the grain count and sizes, the
  /// friction and the scalars of unbalanced_force_ratio(): with a device backend, the driver
  /// then brings the whole state to the host first (backend/stepper.hpp). When unsure, true.
  virtual bool reads_grains(const Simulation& sim) const {
    (void)sim;
    return true;
  }
  /// Extra columns for the time series (stage-specific), in a fixed order.
  virtual Measurement columns(const Simulation& sim) const = 0;
  /// What begin() and update() have set up and counted so far, declared once for saving and
  /// loading (checkpoints: core/state_io.hpp); loading it replaces begin() when a run resumes.
  virtual void state(StateArchive& a) = 0;
};

/// The place a grain cloud starts from, drawn from the grading (sizes) and placed without
/// overlap in a loose cube with its lower corner at the origin, or a loose cylinder about the z
/// axis with its base at z = 0.
struct LooseCloud {
  std::vector<Vec3> position;
  std::vector<double> radius;
  double side = 0.0;    // loose cube side, or cylinder diameter [m]
  double height = 0.0;  // loose height [m]
  double sector = 1.0;  // the fraction of the circle a cylinder fills
};
/// The grains (sizes and places) of the loose cloud; `place = false`: its size only.
LooseCloud make_loose_cloud(const SampleConfig& cfg, bool place = true);

/// The chamber of a cylindrical sample whose loose cloud is `cloud`: a dilating cylinder_inside
/// of the cloud's diameter about the z axis, reaching a cloud's height
/// below and above it (the platens move within it), fixed until a controller sets it, with the
/// box walls' friction. Named "chamber".
BodyConfig chamber_body(const LooseCloud& cloud);

/// The names of the bodies a cylindrical sample adds: the chamber, the symmetry planes x = 0 and
/// y = 0 (no [[body]] may take them).
inline constexpr std::array<const char*, 3> kSampleBodyNames = {"chamber", "symmetry_x",
                                                                "symmetry_y"};

/// The frictionless symmetry planes of a sector: x = 0 for a half ("symmetry_x", the grains at
/// x > 0), and y = 0 too for a quarter ("symmetry_y"); none for a whole cylinder.
std::vector<BodyConfig> symmetry_planes(const LooseCloud& cloud);

/// A chamber sample's bodies: its chamber (chamber_body, raised by `z_bottom`, the bottom
/// platen's height when the sample comes from a file) and its symmetry planes.
std::vector<BodyConfig> chamber_sample_bodies(const LooseCloud& size, double z_bottom);
/// The same for a chamber sample read from a file: its chamber of `radius` and `sector_degrees`
/// between the platens at z_bottom and z_top (the file's box).
std::vector<BodyConfig> file_chamber_bodies(double radius, double sector_degrees, double z_bottom,
                                            double z_top);

class PreparationController final : public Controller {
 public:
  PreparationController(const SampleConfig& cfg, double material_friction);
  void begin(Simulation& sim) override;
  bool update(Simulation& sim) override;
  std::uint64_t steps_to_check(Simulation& sim) override;
  /// Reads the walls, the grains' sizes and the unbalanced-force ratio only, except while the
  /// grains follow the walls (affine compaction), which sets their velocities.
  bool reads_grains(const Simulation&) const override { return phase_ == Phase::Affine; }
  Measurement columns(const Simulation& sim) const override;
  void state(StateArchive& a) override;
  double preparation_friction() const { return mu_found_; }
  double void_ratio() const { return e_; }
  /// Empty when the target was reached; otherwise what went wrong.
  const std::string& warning() const { return warning_; }

 private:
  // Saved by value in checkpoints: a new phase goes at the end.
  enum class Phase { Compact, Settle, Done, Affine };
  SampleConfig cfg_;
  double mu_material_;
  double mu_ = 0.0, mu_found_ = 0.0, e_ = 0.0;
  Phase phase_ = Phase::Compact;
  std::uint64_t start_step_ = 0;
  std::string warning_;
};

/// Every servo wall within `tol` of its target (relative; a zero target within `tol` of the
/// largest target).
bool servo_walls_at_target(const Walls& w, double tol);

}  // namespace crushdem
