//! Configuration of `lopd`: the scene files and the daemon configuration, read from TOML,
//! validated, and turned into plain typed structs.
//!
//! Loading has two stages. First the TOML is deserialized into raw structs that reject unknown
//! keys; then every value is range-checked (NaN and infinities fail every check) and resolved
//! (relative paths, defaults). Any failure is a [`ConfigError`] whose message names the file, the
//! line and column where known, the key path (`body[2].fem.young`), the body's name and the
//! offending value, e.g.
//!
//! ```text
//! config/scenes/organs.toml:115:9: body[2].fem.young = -5.0 (body "stomach"): Young's modulus (Pa) must be a finite number > 0
//! ```
//!
//! Nothing in this crate panics on any input.
//!
//! # Finding a scene
//!
//! [`resolve_scene`] takes a name or a path. A name (no `/`, no `.toml` suffix) is looked up as
//! `NAME.toml` in, in order: each directory of `$LOP_SCENE_DIR` (`:`-separated), this crate's
//! `scenes/` folder, `/usr/share/lop/scenes`. Shipped scenes: `abdomen` (the default of `lopd`:
//! the organs with soft-tissue values from the literature, sources in its comments), `beam`
//! (thesis ch. 3), `cylinders` (§6.1) and `organs` (§6.2, the thesis' reproduction). Mock-device
//! scripts resolve the same way through
//! [`resolve_script`] (`$LOP_SCRIPT_DIR`, this crate's `scripts/`, `/usr/share/lop/scripts`).
//!
//! # Scene files
//!
//! Units are SI throughout (m, kg, s, N, Pa, W); the scene frame is right-handed with y up.
//! Every table and key is listed below; any other key is an error. A key with a default may be
//! left out; a table whose keys all have defaults may be left out.
//!
//! ```toml
//! [scene]
//! name = "organs"
//! description = "Liver, spleen, stomach and pancreas (thesis §6.2)"
//! gravity = [0.0, 0.0, 0.0]
//!
//! [tool]
//! radius = 0.003
//! force_law = "linear"
//! stiffness = 300.0
//! damping = 0.0
//! max_force = 3.0
//! heat_power = 20.0
//!
//! [workspace]
//! scale = 2.0
//! rotate_deg = [0.0, 0.0, 0.0]
//! offset = [-0.018, 0.048, -0.005]
//!
//! [rates]
//! haptic_hz = 1000.0
//! deform_max_hz = 1000.0
//! publish_hz = 250.0
//!
//! [device]
//! mock_script = "../scripts/organs-poke.toml"
//!
//! [heat]
//! air_temperature = 22.0
//! air_coefficient = 10.0
//! contact_conductance = 500.0
//!
//! [[body]]
//! name = "liver"
//! mesh = "../../assets/meshes/liver"
//! importance = "important"
//!
//! [body.fem]
//! young = 140.0
//! poisson = 0.023
//! density = 10.0
//! damping = 10.0
//! dt = 0.01
//!
//! [body.msd]
//! stiffness = 2.7
//! density = 10.0
//! damping = 4e-4
//! dt = 0.01
//! integrator = "implicit-euler"
//!
//! [body.gc]
//! cage = "fitted"
//! dynamics = "projected"
//! stiffness = 50.0
//! density = 20.0
//! damping = 0.3
//! dt = 0.02
//!
//! [body.heat]
//! conductivity = 0.52
//! specific_heat = 3540.0
//! density = 1060.0
//! initial = 37.0
//! coagulation = 60.0
//! burn_stiffening = 1.0
//! ```
//!
//! ## `base` (optional, top level)
//! `base = "abdomen.toml"` (a path relative to this file) writes this scene over another: the
//! base's bodies, `[lop]`, `[heat]`, `[collision]` and `[cut]`, with this file's `[scene]`, tools
//! (`[tool]` or `[[tool]]`), `[workspace]`, `[rates]` and `[device]` where it gives them — other
//! tools, devices or mappings over the same organs without copying them. Each section given
//! replaces the base's whole; tools given here map with this file's `[workspace]` (the default
//! mapping if it gives none), never the base's. A body, `[lop]`, `[heat]` or `[collision]`
//! beside `base` is refused naming it. The base is read as a scene of its own first, so its
//! errors name its file and line; a base may stand on another, up to four deep. The shipped
//! `abdomen-two-hands` is written over `abdomen`.
//!
//! ## `[scene]` (optional)
//! | key | type | default | meaning |
//! |---|---|---|---|
//! | `name` | string | file name without `.toml` | shown by viewers and logs; non-empty |
//! | `description` | string | `""` | free text |
//! | `gravity` | `[x, y, z]` | `[0, 0, 0]` | m/s²; y is up, so Earth is `[0, -9.81, 0]`. Off by default: an organ without fixed nodes would fall away |
//!
//! ## `[tool]` (optional)
//! The tool tip is a sphere driven by the device and rendered as a god-object: it stays on the
//! tissue surface while the device penetrates, and the force pushes the device back out.
//! Without the section a scene gets the defaults below; a `[tool]` section must give `radius`
//! and `stiffness` itself (they decide what the hand feels, and `stiffness`' unit depends on
//! `force_law`), or it is refused naming the missing key.
//!
//! | key | type | default | meaning |
//! |---|---|---|---|
//! | `radius` | float | required in `[tool]` (`0.003` without the section) | tip radius, m (> 0) |
//! | `force_law` | `"linear"` \| `"quadratic"` | `"linear"` | `linear`: `F = k d N`; `quadratic`: thesis eq. 5.2, `F = k d² N` (`d` penetration depth, `N` surface normal) |
//! | `stiffness` | float | required in `[tool]` (`300` without the section) | `k`: N/m for `linear`, N/m² for `quadratic` (> 0) |
//! | `damping` | float | `0` | N·s/m on the penetration speed (>= 0) |
//! | `max_force` | float | `3.0` | N, force clamp for this scene (> 0); the daemon clamps to the smallest of this, `haptic.max_force_n` and the device's limit |
//! | `heat_power` | float | `20` | W delivered by the cautery button (>= 0), spread over the touched surface triangle's nodes by the contact point's barycentric weights (see `[heat]`) |
//! | `cut_power` | float | `80` | W delivered while the cut button is held (>= 0), spread as `heat_power`; the tissue it vaporises is cut away where the body allows it (`[cut]`). An electrosurgical generator's cut mode delivers tens of watts to a few hundred |
//! | `name` | string | `"tool"` (the N-th of several: `"toolN"`) | shown in logs and by viewers; unique in the scene |
//! | `kind` | `"probe"` \| `"grasper"` \| `"hook"` | `"probe"` | what the device's buttons do: a `probe`'s grab button holds the tissue at the point it touches and its heat button cauterizes; a `grasper`'s grab button closes its jaws, which hold the surface within `jaw_radius` of that point until the button opens them, and it does not cauterize (`heat_power` refused); a `hook` cauterizes and does not hold (its grab button is ignored). Every kind presses with its tip. A cautery (`probe`, `hook`) also cuts with the cut button where the body allows it (`[cut]`). `"blade"` is refused: a blade's sweeping cut is not built yet |
//! | `jaw_radius` | float | the tool's `radius` | a grasper's jaws: how far around the touched point they hold the surface, m (> 0); refused on another kind |
//! | `workspace` | table | the scene's `[workspace]` | this tool's device mapping, same keys as `[workspace]` |
//! | `mock_script` | string | none (the first tool: `[device] mock_script`) | the script a scripted device (`mock`, `hand`) driving this tool plays when the command line names none, relative to the scene file |
//!
//! **Several tools** (two hands, a grasper beside a hook): write `[[tool]]` tables instead of one
//! `[tool]`, one per tool in the order devices are given to them (`lopd run --device A --device
//! B`: the first device drives the first tool), at most four, each with the keys above. The
//! deformation process gathers every tool's contact patch in the same round, so tissue pinched
//! between two tools pushes back on both.
//!
//! Stiffness felt at the stylus is `stiffness × workspace.scale`. A Phantom Omni renders about
//! 0.7 N/mm stably; the shipped scenes use 300 N/m at scale ≤ 2, i.e. ≤ 0.6 N/mm.
//!
//! ## `[workspace]` (optional)
//! Maps device positions (mm, device frame) into the scene (m):
//! `scene = R(rotate_deg) · (device_mm · 0.001 · scale) + offset`. Forces are only rotated back,
//! never scaled. See [`WorkspaceMap`].
//!
//! | key | type | default | meaning |
//! |---|---|---|---|
//! | `scale` | float | `1.0` | scene metres per device metre (> 0) |
//! | `rotate_deg` | `[x, y, z]` | `[0, 0, 0]` | degrees: about x, then y, then z, fixed axes (`R = Rz·Ry·Rx`, see [`rotation_xyz_deg`]) |
//! | `offset` | `[x, y, z]` | `[0, 0, 0]` | m: where the device origin lands in the scene |
//!
//! ## `[rates]` (optional)
//! | key | type | default | meaning |
//! |---|---|---|---|
//! | `haptic_hz` | float | `1000` | haptic loop rate, Hz (100..=10000) |
//! | `deform_max_hz` | float | `1000` | upper bound on deformation steps per second (> 0) |
//! | `publish_hz` | float | `250` | upper bound on frames published per second (> 0) |
//!
//! ## `[device]` (optional)
//! | key | type | default | meaning |
//! |---|---|---|---|
//! | `mock_script` | path | none | script the mock device plays when none is given on the command line; relative to the scene file. Checked by the mock driver when used, so the scene still loads on a rig with a real device |
//!
//! ## `[lop]` (optional): levels of precision (thesis §4.4)
//! Bodies with `model = "auto"` run as a Green-coordinates cage while untouched, switch to their
//! precise model (FEM if important, mass-spring otherwise) when the tool comes within 2 mm, and
//! hand back to the cage once settled. The hand-over fits the cage to the precise shape and fades
//! what the cage cannot represent out over `blend`, so nothing pops.
//!
//! | key | type | default | meaning |
//! |---|---|---|---|
//! | `rest_speed` | float | `0.002` | m/s (> 0): a precise body is settled while its fastest node is slower than this … |
//! | `hold` | float | `0.3` | … for this long without tool contact, s (>= 0) |
//! | `blend` | float | `0.2` | s (>= 0): fade-out of the residual shape after a hand-over to the cage; 0 snaps |
//! | `start` | `"gc"` \| `"precise"` | `"gc"` | level every `auto` body starts at; `precise` lets bodies settle under gravity precisely first (thesis fig. 6.5) |
//!
//! ## `[heat]` (optional): heat and burns (thesis §5.3)
//! Heat diffuses through each body (`ρc ∂T/∂t = ∇·(k∇T) + q`, linear tetrahedra, backward
//! Euler: conservative and stable at any step; see `lop_sim::heat`), leaves to the air at the
//! surface and crosses between organs that touch. Temperatures in °C, powers in W.
//!
//! | key | type | default | meaning |
//! |---|---|---|---|
//! | `air_temperature` | float | `22` | °C (above -273.15, at most 1000) |
//! | `air_coefficient` | float | `10` | convective heat-transfer coefficient `h` from tissue surfaces to the air, W/m²/K (>= 0; 10 is natural convection; 0 insulates) |
//! | `contact_conductance` | float | `500` | W/m²/K (>= 0) between touching organs, times the contact area (≈ tissue conductivity 0.5 W/m/K across a 1 mm layer; 0: no heat crosses) |
//! | `dt` | float | `0.01` | heat time step, s (0 < dt <= 1); the scheme is stable at any step, so a longer one only costs accuracy |
//!
//! ## `[collision]` (optional): organs push each other (thesis §6.3.4.1)
//! At every detection (each round in which a body steps, or once per `interval`), surface
//! vertices of each body inside another body (or within `skin` of it) become pairs of contact
//! springs, one on the vertex and one on the other body's
//! closest point, each pushing its side half the depth apart; every model resolves them
//! implicitly in its own step, a cage through its cage (see `lop_sim::collide`). Stiffer
//! springs let the surfaces sink less into each other (`2F/k` per vertex pair under a force
//! `F`) but, being anchored where the contact was at the start of the step, also drag on a
//! pushed body (a damper of `k·dt` along the normal).
//!
//! | key | type | default | meaning |
//! |---|---|---|---|
//! | `enabled` | bool | `true` | whether bodies push each other |
//! | `stiffness` | float | `20` | N/m (> 0) per contact spring |
//! | `skin` | float | `0.0005` | m (0 to 0.01): contact starts this far before the surfaces meet. The shipped organs are about 1 mm apart at rest, so the default leaves them untouched until pushed |
//! | `depth_limit` | float | `0.01` | m (> 0): vertices deeper than this inside another body are ignored (and the detection stops searching there) |
//! | `interval` | float | `0` | s (0 to 1) of simulated time between two detections; the springs of the last one hold meanwhile. `0`: every round in which a body steps. A body stepping at the haptic rate would otherwise pay for a detection every millisecond; organs that push each other move far slower than the tool |
//!
//! ## `[cut]` (optional): electrosurgical cutting
//! A cautery (`kind = "probe"` or `"hook"`) whose cut button is held heats where it touches
//! as its heat button does, at `cut_power`, and the tissue under its tip that the heat
//! vaporises is cut away: every tetrahedron within two tool radii of the tip with a node at
//! `vaporization` or hotter, of a body that allows it (`[[body]] cut = true`).
//! The new mesh is prepared off the stepping thread and lands `delay_steps` steps of the body
//! later, at the same step in every run. Pieces the cut leaves without a fixed node, or of
//! fewer than 4 tetrahedra, go with it; a cut that would leave nothing of the body is refused.
//! A cut body keeps its precise model (FEM or mass-spring) from then on: its cage cannot
//! represent the wound (see `lop_sim::cut`). Scripts press the cut button as `buttons =
//! ["cut"]`.
//!
//! | key | type | default | meaning |
//! |---|---|---|---|
//! | `vaporization` | float | `100` | °C: tissue vaporises when its intracellular water boils (a node this hot takes its tetrahedra with it) |
//! | `delay_steps` | integer | `50` | 1 to 1000: steps of the body between a cut's request and its landing |
//!
//! ## `[[body]]` (one or more)
//! | key | type | default | meaning |
//! |---|---|---|---|
//! | `name` | string | required | unique within the scene, non-empty |
//! | `mesh` | path | required | relative to the scene file. A TetGen base path (`liver` for `liver.node`, `liver.ele`, optional `liver.face` and `liver.bnd` with the fixed nodes) or a mesh file (`.msh`, `.vtk`). Must exist: `PATH` or `PATH.node` |
//! | `importance` | `"important"` \| `"normal"` | `"normal"` | which precise model the body gets when touched: FEM if important, mass-spring otherwise (thesis §4.4) |
//! | `model` | `"auto"` \| `"gc"` \| `"msd"` \| `"fem"` | `"auto"` | `auto`: the LoP controller decides (GC at rest, precise model when touched, back to GC once settled); anything else pins the body to that model |
//! | `scale` | float | `1.0` | uniform scale of the mesh nodes (> 0), applied first |
//! | `rotate_deg` | `[x, y, z]` | `[0, 0, 0]` | rotation after scaling, same convention as the workspace |
//! | `translate` | `[x, y, z]` | `[0, 0, 0]` | m, applied last: `p' = R·(scale·p) + translate` |
//! | `fixed_nodes` | array of integers | `[]` | 0-based node indices held fixed, in addition to the `.bnd` file |
//! | `fix` | array of tables | `[]` | fixed-node selectors, `[[body.fix]]` below: every node one of them picks is fixed too |
//! | `color` | `[r, g, b]` | by body index | sRGB, each in 0..=1, for viewers |
//! | `tool_stiffness` | float | `[tool] stiffness` | stiffness of the tool against this body (> 0; N/m for the linear law, N/m² for the quadratic one): a firm organ feels firmer |
//! | `cut` | bool | `false` | a cautery's cut button cuts this body (`[cut]`); refused with `model = "gc"`, whose cage cannot represent a cut |
//!
//! ### `[[body.fix]]`: fixed nodes by region
//! Where a `.bnd` file or a list of node numbers is awkward (a mesh fresh from a mesher, or one
//! remeshed finer), a body fixes the nodes in a region. The fixed nodes are the union of the
//! `.bnd` file, `fixed_nodes` and every selector.
//!
//! **Coordinates: the scene's**, in metres — a selector is evaluated on the body's nodes after
//! its `scale`, `rotate_deg` and `translate`, because that is where the author places the body
//! and sees it (a viewer, the device mapping, the other bodies are all in scene coordinates).
//! `lopd mesh info MESH --select '…'` shows what a selector picks in the mesh file's own
//! coordinates; for a body with no transform the two are the same.
//!
//! A selector that picks no node is an error naming the body and the selector (`body[0].fix[1]`)
//! when the scene is loaded (`lopd run` checks it before starting).
//!
//! | `kind` | keys | picks |
//! |---|---|---|
//! | `"box"` | `min`, `max` (`[x, y, z]`, m; `min < max` per axis) | nodes inside the box (boundary included) |
//! | `"sphere"` | `center` (m), `radius` (m, > 0) | nodes within `radius` of `center` |
//! | `"slab"` | `point` (m), `normal` (not zero), optional `thickness` (m, > 0) | nodes behind the plane through `point`, i.e. on the side `normal` points away from (`(p − point)·n̂ <= 0`), at most `thickness` behind it if given |
//! | `"facing"` | `direction` (not zero), `angle_deg` (0 < a <= 180, default 45), optional `within` (another selector, as an inline table) | surface nodes whose outward normal (area-weighted mean of their triangles' normals) is within `angle_deg` of `direction`, and inside `within` if given |
//!
//! A key of another kind (`radius` on a box) is refused naming it. For example, the back of an
//! organ whose posterior side is at `z = -0.04`, and a ligament:
//!
//! ```toml
//! [[body.fix]]
//! kind = "facing"
//! direction = [0.0, 0.0, -1.0]
//! angle_deg = 60.0
//! within = { kind = "slab", point = [0.0, 0.0, -0.03], normal = [0.0, 0.0, 1.0] }
//!
//! [[body.fix]]
//! kind = "sphere"
//! center = [0.05, 0.02, 0.0]
//! radius = 0.005
//! ```
//!
//! A body needs the parameter tables of every model it can run:
//! - `[body.fem]` if `importance = "important"` or `model = "fem"`;
//! - `[body.msd]` unless `model = "fem"`: mass-spring is every body's fallback;
//! - `[body.gc]` optional: without it a cage runs with the defaults below;
//! - `[body.heat]` optional: without it the body has the liver-like defaults below.
//!
//! ### `[body.fem]`: linear tetrahedral FEM (thesis §4.2)
//! | key | type | default | meaning |
//! |---|---|---|---|
//! | `young` | float | required | Young's modulus E, Pa (> 0) |
//! | `poisson` | float | required | Poisson's ratio ν, 0 <= ν < 0.5 |
//! | `density` | float | required | kg/m³ (> 0); masses are lumped per node |
//! | `damping` | float | required | α of the damping matrix `D = α M`, 1/s (>= 0) |
//! | `dt` | float | required | time step, s (0 < dt <= 1). At the haptic rate (`dt <= 1 / [rates] haptic_hz`, as in `abdomen`: a body's precise model runs while the tool touches it) a corotational body never refactorises its solver's factor in a step (no millisecond spikes on the hand's path); slower, it refactorises when that saves work overall |
//! | `mode` | `"corotational"` \| `"linear"` | `"corotational"` | `linear` is the thesis' formulation and inflates under large rotations; `corotational` warps the stiffness by each element's rotation |
//!
//! ### `[body.msd]`: mass-spring-damper (thesis §4.1, eq. 4.2)
//! Springs on the mesh edges.
//!
//! | key | type | default | meaning |
//! |---|---|---|---|
//! | `stiffness` | float | required | spring constant, N/m (> 0) |
//! | `density` | float | one of these two | kg/m³ (> 0): node masses lumped from tetrahedron volumes |
//! | `node_mass` | float | one of these two | kg (> 0): the same mass for every node |
//! | `damping` | float | required | γ of eq. 4.2, N·s/m per node (>= 0) |
//! | `dt` | float | required | time step, s (0 < dt <= 1) |
//! | `integrator` | string | `"symplectic-euler"` | `"explicit-euler"`, `"symplectic-euler"`, `"verlet"`, `"rk4"` or `"implicit-euler"`; explicit ones are stable only below a limit: symplectic Euler and Verlet need `dt < 2/ω_max`, which `dt < min over nodes of 2·sqrt(m / (2 Σk))` guarantees (Σk: stiffness of the node's springs); implicit Euler is stable at any `dt` |
//!
//! ### `[body.gc]`: Green-coordinates cage (thesis §4.3; Tables 6.1, 6.2)
//! Used while the body rests under `model = "auto"`, and always under `model = "gc"`.
//!
//! | key | type | default | meaning |
//! |---|---|---|---|
//! | `cage` | `"fitted"` \| `"box"` \| `"subdivided-box"` | `"fitted"` | `fitted`: the padded bounding box cut into roughly cubic cells, `round(extent / smallest extent)` segments per axis (a cylinder twice as tall as wide gets 1 × 2 × 1); `box`: the thesis' padded bounding box (8 vertices, 12 triangles), cheapest, but a long body cannot bend inside it; `subdivided-box`: the box with each edge cut into `subdivisions` segments (`6n²+2` vertices), closest to the precise model, dearest per step |
//! | `subdivisions` | integer | `2` | segments per edge for `subdivided-box` (1..=8) |
//! | `padding` | float | 5 % of the body's smallest extent | m (> 0): gap between the body's bounding box and the cage (no node may lie on the cage) |
//! | `dynamics` | `"projected"` \| `"galerkin"` \| `"mass-spring"` | `"projected"` | `projected`: the body's precise model (FEM if important, else mass-spring) projected onto the cage's motions with the stiffness matched to its compliance, nothing to tune, the accurate default; `galerkin`: the plain Galerkin projection (stiffer than the body, for comparison); `mass-spring`: the thesis' cage with the hand-tuned parameters below |
//! | `stiffness` | float | required for `mass-spring` | N/m (> 0), between every pair of cage vertices |
//! | `density` | float | required for `mass-spring` | kg/m³ (> 0): cage volume × density, shared by its vertices |
//! | `damping` | float | required for `mass-spring` | N·s/m per cage vertex (>= 0) |
//! | `dt` | float | the precise model's `dt` | time step, s (0 < dt <= 1) |
//!
//! ### `[body.heat]`: thermal tissue properties (thesis §5.3)
//! The defaults are liver-like soft tissue (typical literature values, e.g. the IT'IS
//! Foundation tissue database); diffusivity `α = k / (ρ c)` ≈ 1.4e-7 m²/s.
//!
//! | key | type | default | meaning |
//! |---|---|---|---|
//! | `conductivity` | float | `0.52` | thermal conductivity `k`, W/m/K (> 0) |
//! | `specific_heat` | float | `3540` | specific heat capacity `c`, J/kg/K (> 0) |
//! | `density` | float | `1060` | kg/m³ (> 0) for the heat capacity; independent of `[body.fem]`/`[body.msd]` densities, which are tuned for the dynamics |
//! | `initial` | float | `37` | initial (body) temperature, °C (above -273.15, at most 1000) |
//! | `coagulation` | float | `60` | °C, above `initial`: a node hotter than this is burned (shown by viewers) until the scene is reset |
//! | `burn_stiffening` | float | `1.0` | stiffness factor of burned tissue (> 0); 1 = off, e.g. 3 makes coagulated tissue three times stiffer |
//!
//! # Daemon configuration
//!
//! `lopd --config PATH` reads a [`DaemonConfig`]. Every key has a default; an empty file is valid.
//!
//! | key | type | default | meaning |
//! |---|---|---|---|
//! | `status_interval_ms` | integer | `500` | status report interval, ms (> 0) |
//! | `haptic.core` | integer | last core | CPU the real-time thread is pinned to |
//! | `haptic.rt_priority` | integer | `80` | `SCHED_FIFO` priority, 1..=99 |
//! | `haptic.lock_memory` | bool | `true` | `mlockall` the haptic process |
//! | `haptic.stale_frame_ms` | float | `100` | a scene frame older than this ramps the force to zero (> 0) |
//! | `haptic.ramp_ms` | float | `5` | ramp-down time to zero force, 0..=100 ms |
//! | `haptic.max_force_n` | float | `3.0` | global force clamp, N (> 0) |
//! | `haptic.spin_us` | float | `50` | busy-wait before each deadline, 0..=1000 µs |
//! | `haptic.max_force_step_n` | float | `0.05` | largest force change per tick beyond what the stylus's motion explains (the tool spring times its move), contact onset included, N (> 0, <= `max_force_n`) |
//! | `haptic.local_model` | bool | `true` | between frames, render with the frame's local model of the contact patch (the force follows the hand tick by tick); `false`: against the frame's surface alone |
//! | `haptic.passivity_max_damping` | float | `5` | most damping the passivity controller at the device port adds, N·s/m (0..=40; 0: off) |
//! | `deform.core` | integer | not pinned | CPU the deformation thread is pinned to |
//! | `deform.threads` | integer | `0`: every core but one, at least 1 | threads the touched body's FEM step runs on (results are bit for bit the same for any count); more than the machine's cores is refused |
//! | `deform.max_period_ms` | integer | `10` | longest period a touched body may step at where its step costs more than its own period, 1..=100 ms |
//! | `deform.rt_priority` | integer | `40` (at most `haptic.rt_priority` − 2) | `SCHED_FIFO` priority of the deformation thread, below the haptic loop's frame thread (`haptic.rt_priority` − 1); `0`: the normal scheduler. Not permitted: runs normally, with a warning |
//! | `device.hd_library` | path | search `libHD.so` | OpenHaptics library for `--device openhaptics` (relative to the config file; `LOP_HD_LIBRARY` wins) |
//! | `device.dhd_library` | path | search `libdhd.so` | Force Dimension DHD library for `--device dhd` (relative to the config file; `LOP_DHD_LIBRARY` wins; not empty) |
//!
//! ```toml
//! status_interval_ms = 500
//! [haptic]
//! core = 1
//! rt_priority = 80
//! [deform]
//! core = 0
//! ```

mod check;
mod daemon;
mod error;
mod raw;
mod remote;
mod resolve;
mod scene;
mod source;
mod tissue;

pub use daemon::{
    default_deform_threads, load_daemon_config, machine_cores, parse_daemon_config, DaemonConfig,
    DeformConfig, DeviceConfig, HapticConfig,
};
pub use error::{ConfigError, Location};
pub use remote::{
    check_zenoh_endpoint, RemoteConfig, RemoteOverrides, ZenohMode, DEFAULT_LISTEN,
    DEFAULT_REMOTE_FRAME_RATE_HZ, DEFAULT_TUNNEL, REMOTE_SERVICES,
};
pub use resolve::{
    list_scenes, list_scenes_in, list_scripts, resolve_scene, resolve_scene_in, resolve_script,
    scene_dirs, script_dirs,
};
pub use scene::{
    load_scene, parse_scene, parse_selector, selector_toml, BodySpec, CollisionSpec, CutSpec,
    DeviceDefaults, GcParams, HeatParams, HeatSpec, Importance, LopSpec, Rates, Scene, ToolKind,
    ToolSpec,
};
// The value types a scene names are `lop-sim`'s (one owner each, read through its `serde`
// feature); re-exported so a reader of a scene needs only this crate.
pub use lop_sim::contact::ForceLaw;
pub use lop_sim::fem::{FemMode, FemParameters};
pub use lop_sim::lop::StartLevel;
pub use lop_sim::mesh::NodeSelector;
pub use lop_sim::model::ModelPin;
pub use lop_sim::msd::{Integrator, MsdParameters, NodeMass};
pub use tissue::{tissue, tissue_names, Tissue, MSD_CALIBRATION, TISSUES};
// The device-to-scene map is physics (the haptic pipeline applies it every tick); the scene
// schema names it.
pub use lop_sim::haptic::workspace::{
    mat_t_vec, mat_vec, rotation_xyz_deg, Mat3, WorkspaceMap, WorkspaceTransform,
};
