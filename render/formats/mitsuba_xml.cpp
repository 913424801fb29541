// Mitsuba 3 XML import (the subset in mitsuba_xml.h; the export is in mitsuba_xml_export.cpp).
// Import runs in two passes, as Mitsuba's parser does: (1) load the documents in order,
// substituting $parameters element by element and splicing in <include>d files, and register
// every `id`; (2) interpret the top-level objects in document order, resolving <ref>s by id (so
// forward references work). The element-level helpers it builds on (attribute and number checks,
// transforms, Props, the sensor's field of view) are in mitsuba_xml_elements.cpp.
#include "render/formats/mitsuba_xml.h"

#include <tinyxml2.h>

#include <cmath>
#include <map>
#include <memory>
#include <set>

#include "core/check.h"
#include "core/file_util.h"
#include "core/image_io.h"
#include "core/ply_io.h"
#include "render/formats/mesh_sources.h"
#include "render/formats/mitsuba_xml_internal.h"

namespace genscene::render {

namespace {

namespace fs = std::filesystem;
using Eigen::Matrix3d;
using Eigen::Matrix4d;
using Eigen::Vector3d;
using Eigen::Vector3f;
using mitsuba_detail::Affine;
using mitsuba_detail::CheckAttributes;
using mitsuba_detail::Fail;
using mitsuba_detail::HorizontalFov;
using mitsuba_detail::IsObjectTag;
using mitsuba_detail::Number;
using mitsuba_detail::PlyColorAttribute;
using mitsuba_detail::Props;
using mitsuba_detail::Radians;
using mitsuba_detail::RequiredAttribute;
using mitsuba_detail::SplitCameraToWorld;
using mitsuba_detail::Tokens;
using mitsuba_detail::Type;
using mitsuba_detail::Where;
using tinyxml2::XMLDocument;
using tinyxml2::XMLElement;

// ------------------------------------------------------------------------------------------------
// The importer.

// A diffuse BSDF's reflectance: a constant, or a mesh attribute of the shape times `scale`.
struct Reflectance {
  Vector3f constant = Vector3f::Constant(0.5f);
  std::string attribute;  // "vertex_color" or "face_color"; empty for the constant
  float scale = 1.0f;
};

class Importer {
 public:
  Importer(const fs::path& path, const MitsubaImportOptions& options)
      : main_file_(path), options_(options) {
    for (const auto& [name, value] : options.parameters) params_[name] = value;
    if (options.sphere_subdivision_level < 0 || options.sphere_subdivision_level > 8) {
      throw Error(Format("sphere_subdivision_level ", options.sphere_subdivision_level,
                         " is not in [0, 8]"));
    }
  }

  LoadedScene Run() {
    search_.push_back(main_file_.parent_path());
    LoadFile(main_file_, nullptr, 0);
    for (XMLElement* el : top_) Interpret(el);
    for (XMLElement* el : top_) {
      if (std::string(el->Name()) == "emitter" && Type(el) == "area" && !referenced_.count(el)) {
        out_.warnings.push_back(Where(el) +
                                ": area emitter not attached to any shape; ignored, as "
                                "Mitsuba ignores it");
      }
    }
    if (!out_.settings.integrator) {  // Mitsuba's default integrator
      out_.settings.integrator = "path";
      out_.settings.max_depth = -1;
    }
    out_.scene.Validate();
    return std::move(out_);
  }

 private:
  // Pass 1 --------------------------------------------------------------------------------------

  void LoadFile(const fs::path& file, const XMLElement* include, int depth) {
    if (depth > 16) Fail(include, "includes nested more than 16 deep (a cycle?)");
    auto doc = std::make_unique<XMLDocument>();
    files_.push_back(std::make_unique<fs::path>(file));
    doc->SetUserData(files_.back().get());
    if (!fs::is_regular_file(file)) {
      const std::string what = Format(file.string(), ": file not found");
      if (include) Fail(include, what);
      throw Error(what);
    }
    const std::string text = ReadTextFile(file);
    if (doc->Parse(text.data(), text.size()) != tinyxml2::XML_SUCCESS) {
      throw Error(Format(file.string(), ":", doc->ErrorLineNum(), ": malformed XML (",
                         doc->ErrorName(), ")"));
    }
    XMLElement* root = doc->RootElement();
    if (!root) throw Error(Format(file.string(), ": no root element"));
    if (std::string(root->Name()) != "scene") Fail(root, "the root element must be <scene>");
    CheckAttributes(root, {"version"});
    const std::vector<std::string> version = Tokens(RequiredAttribute(root, "version"));
    if (version.size() != 1 || Number(version[0].substr(0, version[0].find('.')), root) < 2.0) {
      Fail(root, "version must be 2.x or 3.x (older files use names outside the subset)");
    }
    XMLDocument* raw = doc.get();
    docs_.push_back(std::move(doc));
    Walk(raw->RootElement(), file, depth);
  }

  void Walk(XMLElement* scene, const fs::path& file, int depth) {
    for (XMLElement* el = scene->FirstChildElement(); el; el = el->NextSiblingElement()) {
      SubstituteTree(el);
      const std::string tag = el->Name();
      if (tag == "default") {
        CheckAttributes(el, {"name", "value"});
        params_.emplace(RequiredAttribute(el, "name"),
                        RequiredAttribute(el, "value"));  // first wins
      } else if (tag == "include") {
        CheckAttributes(el, {"filename"});
        const std::string name = RequiredAttribute(el, "filename");
        LoadFile(Resolve(name, file.parent_path()), el, depth + 1);
      } else if (tag == "path") {
        CheckAttributes(el, {"value"});
        const fs::path p(RequiredAttribute(el, "value"));
        search_.push_back(p.is_absolute() ? p : file.parent_path() / p);
      } else if (IsObjectTag(tag)) {
        RegisterIds(el);
        top_.push_back(el);
      } else {
        Fail(el, "unexpected element at the top level of <scene>");
      }
    }
  }

  // $name substitution in every attribute (§2): longest defined name first, "\$" escapes.
  void SubstituteTree(XMLElement* el) {
    for (const tinyxml2::XMLAttribute* a = el->FirstAttribute(); a; a = a->Next()) {
      const std::string value = a->Value();
      if (value.find('$') == std::string::npos) continue;
      std::string out;
      for (size_t i = 0; i < value.size(); ++i) {
        if (value[i] == '\\' && i + 1 < value.size() && value[i + 1] == '$') {
          out += '$';
          ++i;
        } else if (value[i] == '$') {
          const std::string* best = nullptr;
          for (const auto& [name, v] : params_) {
            if (value.compare(i + 1, name.size(), name) == 0 &&
                (!best || name.size() > best->size()))
              best = &name;
          }
          if (!best) {
            size_t j = i + 1;
            while (j < value.size() &&
                   (std::isalnum(static_cast<unsigned char>(value[j])) || value[j] == '_'))
              ++j;
            Fail(el, Format("undefined parameter: $", value.substr(i + 1, j - i - 1)));
          }
          out += params_.at(*best);
          i += best->size();
        } else {
          out += value[i];
        }
      }
      el->SetAttribute(a->Name(), out.c_str());
    }
    for (XMLElement* c = el->FirstChildElement(); c; c = c->NextSiblingElement()) SubstituteTree(c);
  }

  void RegisterIds(XMLElement* el) {
    if (IsObjectTag(el->Name()) && el->Attribute("id")) {
      if (!ids_.emplace(el->Attribute("id"), el).second) Fail(el, "duplicate id");
    }
    for (XMLElement* c = el->FirstChildElement(); c; c = c->NextSiblingElement()) RegisterIds(c);
  }

  // A relative file name: first against `first` (when given), then the search folders.
  fs::path Resolve(const std::string& name, const fs::path& first) const {
    const fs::path p(name);
    if (p.is_absolute()) return p;
    if (!first.empty() && fs::exists(first / p)) return first / p;
    for (const fs::path& folder : search_) {
      if (fs::exists(folder / p)) return folder / p;
    }
    return (first.empty() ? search_.front() : first) / p;  // not found: the reader says so
  }

  XMLElement* ResolveRef(XMLElement* ref) {
    const std::string id = RequiredAttribute(ref, "id");
    auto it = ids_.find(id);
    if (it == ids_.end()) Fail(ref, Format("unresolved reference to '", id, "'"));
    referenced_.insert(it->second);
    return it->second;
  }

  Props PropsOf(XMLElement* el) {
    CheckAttributes(el, {"type", "id", "name"});
    return Props(el, [this](XMLElement* ref) { return ResolveRef(ref); });
  }

  // Pass 2 --------------------------------------------------------------------------------------

  void Interpret(XMLElement* el) {
    const std::string tag = el->Name(), type = Type(el);
    if (tag == "shape") {
      ParseShape(el);
    } else if (tag == "emitter" && type == "point") {
      ParsePointEmitter(el);
    } else if (tag == "emitter" && type == "envmap") {
      ParseEnvmap(el);
    } else if (tag == "emitter" && type == "area") {
      ParseAreaEmitter(el);  // validated here; it enters the scene only through a shape (§3)
    } else if (tag == "bsdf") {
      ParseBsdf(el);
    } else if (tag == "sensor") {
      ParseSensor(el);
    } else if (tag == "integrator") {
      ParseIntegrator(el);
    } else if (tag == "emitter") {
      Fail(el, Format("emitter type '", type, "' is not in the subset (area, point, envmap)"));
    } else {
      Fail(el, "this object is not in the subset at the top level");
    }
  }

  Reflectance ParseBsdf(XMLElement* el) {
    if (auto it = bsdfs_.find(el); it != bsdfs_.end()) return it->second;
    if (Type(el) != "diffuse")
      Fail(el, Format("bsdf type '", Type(el), "' is not in the subset (diffuse)"));
    Props p = PropsOf(el);
    const std::optional<Vector3d> albedo = p.Color("reflectance");
    Reflectance r;
    for (XMLElement* c : p.children()) {
      if (!r.attribute.empty() || albedo) Fail(c, "the reflectance is given twice");
      r = ParseMeshAttribute(c);
    }
    p.Finish();
    if (albedo && (albedo->minCoeff() < 0.0 || albedo->maxCoeff() > 1.0)) {
      Fail(el, Format("reflectance (", albedo->transpose(), ") is not in [0, 1]"));
    }
    if (albedo) r.constant = albedo->cast<float>();
    return bsdfs_[el] = r;
  }

  // A texture in a diffuse BSDF: mesh_attribute vertex_color / face_color as its reflectance.
  Reflectance ParseMeshAttribute(XMLElement* el) {
    if (std::string(el->Name()) != "texture" || Type(el) != "mesh_attribute")
      Fail(el, "not in the subset inside a bsdf (a mesh_attribute texture)");
    if (!el->Attribute("name") || std::string(el->Attribute("name")) != "reflectance")
      Fail(el, "the texture must be the reflectance (name=\"reflectance\")");
    Props p = PropsOf(el);
    Reflectance r;
    r.attribute = p.String("name").value_or("");
    r.scale = static_cast<float>(p.Float("scale").value_or(1.0));
    if (!p.children().empty()) Fail(p.children()[0], "not allowed inside a mesh_attribute");
    p.Finish();
    if (r.attribute != "vertex_color" && r.attribute != "face_color") {
      Fail(el, Format("mesh attribute '", r.attribute,
                      "' is not in the subset (vertex_color, face_color)"));
    }
    if (!(r.scale >= 0.0f)) Fail(el, Format("scale ", r.scale, " is negative"));
    return r;
  }

  // The albedo a mesh_attribute reflectance gives the shape `el` read from the PLY `file`.
  SurfaceAlbedo AttributeAlbedo(const XMLElement* el, const XMLElement* bsdf, const Reflectance& r,
                                const fs::path& file, const TriangleMesh& mesh) {
    if (Type(el) != "ply") Fail(el, "a mesh_attribute reflectance needs a ply shape in the subset");
    const bool faces = r.attribute == "face_color";
    SurfaceAlbedo a;
    a.kind = faces ? SurfaceAlbedo::Kind::kPerFace : SurfaceAlbedo::Kind::kPerVertex;
    a.values = PlyColorAttribute(file, faces ? "face" : "vertex", el);
    const size_t expected = faces ? mesh.faces.size() : mesh.vertices.size();
    if (a.values.size() != expected) {
      Fail(el, Format(a.values.size(), " ", r.attribute, " values for ", expected,
                      faces ? " triangles (a polygon face? Mitsuba's PLY loader takes triangles)"
                            : " vertices"));
    }
    for (size_t i = 0; i < a.values.size(); ++i) {
      a.values[i] *= r.scale;
      if (!a.values[i].allFinite() || a.values[i].minCoeff() < 0.0f ||
          a.values[i].maxCoeff() > 1.0f) {
        Fail(bsdf, Format("reflectance (", a.values[i].transpose(), ") of ", r.attribute, " ", i,
                          " is not in [0, 1]"));
      }
    }
    return a;
  }

  Vector3f ParseAreaEmitter(XMLElement* el) {
    Props p = PropsOf(el);
    const Vector3d radiance = p.Color("radiance").value_or(Vector3d::Ones());
    if (!p.children().empty()) Fail(p.children()[0], "textures are not in the subset");
    p.Finish();
    if (radiance.minCoeff() < 0.0)
      Fail(el, Format("radiance (", radiance.transpose(), ") is negative"));
    return radiance.cast<float>();
  }

  // An envmap (EnvmapDirection) becomes the distant light of the scene's voxel lights: the six
  // lobes E(w) = L sum_k lambda_k max(0, w . d_k) fitted to its texels (least squares weighted by
  // solid angle per lobe colour, then the colours' best rank-1 factor L lambda^T). The envmap
  // genscene writes is such a light and comes back as it was; any other is approximated, with a
  // warning giving the fit's relative error.
  void ParseEnvmap(XMLElement* el) {
    Props p = PropsOf(el);
    const std::optional<std::string> filename = p.String("filename");
    const double scale = p.Float("scale").value_or(1.0);
    const Matrix4d to_world = p.Transform("to_world").value_or(Matrix4d::Identity());
    if (!p.children().empty()) Fail(p.children()[0], "textures are not in the subset");
    p.Finish();
    if (!filename) Fail(el, "missing property 'filename'");
    if (!(scale >= 0.0)) Fail(el, Format("scale ", scale, " is negative"));
    if (out_.scene.voxel_lights && out_.scene.voxel_lights->distant)
      Fail(el, "a second envmap: the subset holds one");
    const fs::path file = Resolve(*filename, fs::path());
    CameraResponse linear;
    linear.kind = CameraResponse::Kind::kLinear;
    const ImageRgb image = ReadColorImage(file, linear);
    const Eigen::Matrix3d rotation = to_world.topLeftCorner<3, 3>();
    Eigen::Matrix<double, 6, 6> gram = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 3> rhs = Eigen::Matrix<double, 6, 3>::Zero();
    const auto lobes = [&](int i, int j) {
      const Vector3d w =
          (rotation * mitsuba_detail::EnvmapDirection(i, j, image.width(), image.height()))
              .normalized();
      Eigen::Matrix<double, 6, 1> a;
      for (int axis = 0; axis < 3; ++axis) {
        a[2 * axis] = std::max(0.0, w[axis]);
        a[2 * axis + 1] = std::max(0.0, -w[axis]);
      }
      return a;
    };
    for (int j = 0; j < image.height(); ++j) {
      const double weight = std::sin(mitsuba_detail::kPi * (j + 0.5) / image.height());
      for (int i = 0; i < image.width(); ++i) {
        const Eigen::Matrix<double, 6, 1> a = lobes(i, j);
        gram += weight * a * a.transpose();
        rhs += weight * a * (scale * image(i, j).cast<double>()).transpose();
      }
    }
    Eigen::Matrix<double, 6, 3> colour = gram.ldlt().solve(rhs).cwiseMax(0.0);
    // The best rank-1 factor colour ~ lambda L^T (power iteration), lambda scaled to a top of 1.
    Eigen::Matrix<double, 6, 1> lambda = Eigen::Matrix<double, 6, 1>::Ones();
    Vector3d light = Vector3d::Zero();
    for (int step = 0; step < 50 && colour.maxCoeff() > 0.0; ++step) {
      light = colour.transpose() * lambda / lambda.squaredNorm();
      if (light.squaredNorm() <= 0.0) break;
      lambda = colour * light / light.squaredNorm();
    }
    const double top = lambda.maxCoeff();
    VoxelLightGrid grid;
    if (out_.scene.voxel_lights) {
      grid = *out_.scene.voxel_lights;
    } else {  // no voxels: one dark voxel
      grid.bounds = Eigen::AlignedBox3d(Vector3d::Constant(-0.5), Vector3d::Constant(0.5));
      grid.dims = Eigen::Vector3i::Ones();
      grid.intensity.assign(1, Eigen::Vector3f::Zero());
      grid.weights.assign(1, {1, 1, 1, 1, 1, 1});
    }
    grid.distant = true;
    if (top > 0.0 && light.maxCoeff() > 0.0) {
      grid.distant_intensity = (light * top).cast<float>();
      for (int k = 0; k < 6; ++k) grid.distant_weights[k] = static_cast<float>(lambda[k] / top);
    } else {
      grid.distant_intensity.setZero();
    }
    double error = 0.0, norm = 0.0;
    for (int j = 0; j < image.height(); ++j) {
      const double weight = std::sin(mitsuba_detail::kPi * (j + 0.5) / image.height());
      for (int i = 0; i < image.width(); ++i) {
        const Vector3d w =
            (rotation * mitsuba_detail::EnvmapDirection(i, j, image.width(), image.height()))
                .normalized();
        const Vector3d fitted = grid.DistantRadiance(w.cast<float>()).cast<double>();
        const Vector3d texel = scale * image(i, j).cast<double>();
        error += weight * (fitted - texel).squaredNorm();
        norm += weight * texel.squaredNorm();
      }
    }
    const double relative = norm > 0.0 ? std::sqrt(error / norm) : 0.0;
    if (relative > 0.01) {
      out_.warnings.push_back(Format(
          Where(el), ": envmap ", file.string(), " approximated by six directional lobes (",
          "relative error ", relative, "); the renderer's distant light holds no finer detail"));
    }
    out_.scene.voxel_lights = grid;
  }

  void ParsePointEmitter(XMLElement* el) {
    Props p = PropsOf(el);
    const std::optional<Vector3d> position = p.Point("position");
    const std::optional<Matrix4d> to_world = p.Transform("to_world");
    const Vector3d intensity = p.Color("intensity").value_or(Vector3d::Ones());
    if (!p.children().empty()) Fail(p.children()[0], "textures are not in the subset");
    p.Finish();
    if (position && to_world) Fail(el, "give only one of 'position' and 'to_world'");
    if (intensity.minCoeff() < 0.0)
      Fail(el, Format("intensity (", intensity.transpose(), ") is negative"));
    PointLight light;
    light.position = position   ? *position
                     : to_world ? Vector3d(to_world->topRightCorner<3, 1>())
                                : Vector3d::Zero();
    light.intensity = intensity.cast<float>();
    out_.scene.point_lights.push_back(light);
  }

  void ParseShape(XMLElement* el) {
    Props p = PropsOf(el);
    fs::path file;
    SceneMesh m = ShapeGeometry(el, &p, &file);
    // At most one BSDF and one emitter, nested or by reference (§3); default BSDF otherwise.
    const XMLElement* bsdf = nullptr;
    const XMLElement* emitter = nullptr;
    Reflectance reflectance;
    for (XMLElement* c : p.children()) {
      const std::string tag = c->Name();
      if (tag != "bsdf" && tag != "emitter") Fail(c, "not allowed inside a shape in the subset");
      const XMLElement*& slot = tag == "bsdf" ? bsdf : emitter;
      if (slot) Fail(c, Format("a shape takes only one ", tag));
      slot = c;
      if (tag == "bsdf") reflectance = ParseBsdf(c);
      if (tag == "emitter" && Type(c) != "area")
        Fail(c, "only area emitters can be attached to shapes");
      if (tag == "emitter") m.emission = ParseAreaEmitter(c);
      referenced_.insert(c);
    }
    if (!bsdf) reflectance.constant = Vector3f::Constant(emitter ? 0.0f : 0.5f);
    m.albedo = reflectance.attribute.empty() ? SurfaceAlbedo::Constant(reflectance.constant)
                                             : AttributeAlbedo(el, bsdf, reflectance, file, m.mesh);
    p.Finish();
    CheckMesh(el, m.mesh);
    out_.scene.meshes.push_back(std::move(m));
  }

  // The shape's triangles in the world frame, with Mitsuba's shading normals (§7).
  // `file` is set to the mesh file of obj and ply shapes.
  SceneMesh ShapeGeometry(XMLElement* el, Props* p, fs::path* file) {
    const std::string type = Type(el);
    const Matrix4d to_world = p->Transform("to_world").value_or(Matrix4d::Identity());
    SceneMesh m;
    m.name = el->Attribute("id") ? el->Attribute("id") : type;
    try {
      if (type == "obj" || type == "ply") {
        const std::optional<std::string> filename = p->String("filename");
        if (!filename) Fail(el, "missing property 'filename'");
        const bool face_normals = p->Boolean("face_normals").value_or(false);
        if (type == "obj") p->Boolean("flip_tex_coords");  // texture coordinates: no effect here
        *file = Resolve(*filename, fs::path());
        if (!el->Attribute("id")) m.name = file->stem().string();
        m.mesh = type == "obj" ? ReadObj(*file) : ReadPly(*file);
        m.mesh.vertex_colors.clear();  // colours only through a mesh_attribute (AttributeAlbedo)
        m.mesh.face_colors.clear();
        TransformMesh(to_world, &m.mesh);
        if (face_normals) m.mesh.normals.clear();
        if (!face_normals && m.mesh.normals.empty()) m.mesh.normals = AngleWeightedNormals(m.mesh);
        m.smooth_shading = !face_normals;
      } else if (type == "rectangle" || type == "cube") {
        p->Boolean("face_normals");  // flat either way
        m.mesh = type == "rectangle" ? RectangleMesh() : CubeMesh();
        TransformMesh(to_world, &m.mesh);
      } else if (type == "sphere") {
        const Vector3d center = p->Point("center").value_or(Vector3d::Zero());
        const double radius = p->Float("radius").value_or(1.0);
        m.mesh = SphereMesh(to_world * Affine(radius * Matrix3d::Identity(), center),
                            options_.sphere_subdivision_level);
        m.smooth_shading = true;
      } else {
        Fail(el, Format("shape type '", type,
                        "' is not in the subset (obj, ply, rectangle, cube, sphere)"));
      }
      m.mesh.Validate(m.name);
    } catch (const Error& e) {
      const std::string what = e.what();
      if (what.rfind(Where(el), 0) == 0) throw;  // already names the element
      Fail(el, what);
    }
    return m;
  }

  // Warnings for what renders differently from what the file seems to say (never fatal).
  void CheckMesh(const XMLElement* el, const TriangleMesh& mesh) {
    // Mitsuba's front side follows the shading normal (§8), ours the winding: they must agree.
    int against = 0;
    for (size_t f = 0; f < mesh.faces.size() && !mesh.normals.empty(); ++f) {
      int below = 0;
      for (int k = 0; k < 3; ++k)
        below += mesh.normals[mesh.faces[f][k]].dot(mesh.FaceNormalScaled(f)) < 0.0f;
      against += below == 3 ? 1 : 0;
    }
    if (against > 0) {
      out_.warnings.push_back(
          Format(Where(el), ": ", against,
                 " triangles have vertex normals opposite "
                 "their winding; Mitsuba's front follows the normals, ours the winding"));
    }
    const int degenerate = CountDegenerateFaces(mesh);
    if (degenerate > 0) {
      out_.warnings.push_back(Format(Where(el), ": ", degenerate, " of ", mesh.faces.size(),
                                     " triangles have zero area (kept; they are never hit)"));
    }
  }

  void ParseSensor(XMLElement* el) {
    if (Type(el) != "perspective")
      Fail(el, Format("sensor type '", Type(el), "' is not in the subset (perspective)"));
    Props p = PropsOf(el);
    int width = 768, height = 576;  // Mitsuba's defaults: hdrfilm, Gaussian filter, 4 spp (§6)
    RenderSettings s;
    s.samples_per_pixel = 4;
    s.pixel_filter = PixelFilter{PixelFilter::Kind::kGaussian, 0.5};
    for (XMLElement* c : p.children()) {
      const std::string tag = c->Name();
      if (tag != "film" && tag != "sampler") Fail(c, "not allowed inside a sensor in the subset");
      if (tag == "film") ParseFilm(c, &width, &height, &s);
      if (tag == "sampler") s.samples_per_pixel = ParseSampler(c);
    }
    const double x_fov = HorizontalFov(el, &p, static_cast<double>(width) / height);
    const double ppo_x = p.Float("principal_point_offset_x").value_or(0.0);
    const double ppo_y = p.Float("principal_point_offset_y").value_or(0.0);
    s.near_clip = p.Float("near_clip").value_or(0.01);
    s.far_clip = p.Float("far_clip").value_or(10000.0);
    p.Float("focus_distance");  // read by Mitsuba's projective base; no effect on a pinhole
    const mitsuba_detail::CameraToWorld to_world =
        SplitCameraToWorld(el, p.Transform("to_world").value_or(Matrix4d::Identity()));
    p.Finish();
    // Mitsuba camera (x left, y up, pixel i covers [i, i+1)) -> OpenCV camera (x right, y down,
    // pixel centres at integers): the formulas in mitsuba_xml.h.
    PosedView view;
    const double t = std::tan(0.5 * Radians(x_fov));
    view.intrinsics.width = width;
    view.intrinsics.height = height;
    view.intrinsics.fx = width / (2.0 * t) * to_world.scale.z() / to_world.scale.x();
    view.intrinsics.fy = width / (2.0 * t) * to_world.scale.z() / to_world.scale.y();
    view.intrinsics.cx = 0.5 * (width - 1) - ppo_x * width;
    view.intrinsics.cy = 0.5 * (height - 1) - ppo_y * height;
    view.world_from_camera.matrix() = to_world.rigid * Eigen::Vector4d(-1, -1, 1, 1).asDiagonal();
    view.timestamp = static_cast<double>(out_.views.size());
    view.intrinsics.Validate(Where(el));
    out_.views.push_back(view);
    RecordSensorSettings(el, s);
  }

  int ParseSampler(XMLElement* el) {
    // The unbiased samplers differ in noise only, not in the image they converge to.
    static const std::set<std::string> unbiased = {"independent", "stratified", "multijitter",
                                                   "orthogonal", "ldsampler"};
    if (!unbiased.count(Type(el)))
      Fail(el, Format("sampler type '", Type(el), "' is not in the subset"));
    Props p = PropsOf(el);
    const long long spp = p.Integer("sample_count").value_or(4);
    p.Integer("seed");
    p.Finish();
    if (spp < 1 || spp > (1 << 20))
      Fail(el, Format("sample_count ", spp, " is not in [1, 1048576]"));
    return static_cast<int>(spp);
  }

  void ParseFilm(XMLElement* el, int* width, int* height, RenderSettings* s) {
    if (Type(el) != "hdrfilm") Fail(el, "film type not in the subset (hdrfilm)");
    Props p = PropsOf(el);
    const long long w = p.Integer("width").value_or(768), h = p.Integer("height").value_or(576);
    if (w < 1 || h < 1 || w > 16384 || h > 16384)
      Fail(el, Format("film size ", w, "x", h, " is not in [1, 16384]"));
    *width = static_cast<int>(w);
    *height = static_cast<int>(h);
    const std::string format = p.String("pixel_format").value_or("rgb");
    if (format != "rgb" && format != "rgba")
      Fail(el, Format("pixel_format '", format, "' is not in the subset (rgb, rgba)"));
    p.String("component_format");  // storage precision only
    p.String("file_format");
    p.Boolean("sample_border");
    for (XMLElement* c : p.children()) {
      if (std::string(c->Name()) != "rfilter") Fail(c, "not allowed inside a film");
      Props fp = PropsOf(c);
      if (Type(c) == "box") {
        s->pixel_filter = PixelFilter{PixelFilter::Kind::kBox, 0.5};
      } else if (Type(c) == "gaussian") {
        s->pixel_filter =
            PixelFilter{PixelFilter::Kind::kGaussian, fp.Float("stddev").value_or(0.5)};
      } else {
        Fail(c, Format("rfilter type '", Type(c), "' is not in the subset (box, gaussian)"));
      }
      fp.Finish();
    }
    p.Finish();
    if (*width < 1 || *height < 1)
      Fail(el, Format("film size ", *width, "x", *height, " is not positive"));
  }

  void RecordSensorSettings(const XMLElement* el, const RenderSettings& s) {
    RenderSettings& o = out_.settings;
    if (out_.views.size() == 1) {
      o.samples_per_pixel = s.samples_per_pixel;
      o.pixel_filter = s.pixel_filter;
      o.near_clip = s.near_clip;
      o.far_clip = s.far_clip;
    } else if (o.samples_per_pixel != s.samples_per_pixel || o.near_clip != s.near_clip ||
               o.far_clip != s.far_clip || o.pixel_filter->kind != s.pixel_filter->kind ||
               o.pixel_filter->stddev != s.pixel_filter->stddev) {
      out_.warnings.push_back(Where(el) +
                              ": sampler, filter or clipping differ from the first "
                              "sensor's; the render settings keep the first sensor's");
    }
  }

  void ParseIntegrator(XMLElement* el) {
    if (out_.settings.integrator) Fail(el, "more than one integrator");
    const std::string type = Type(el);
    Props p = PropsOf(el);
    if (type == "path") {
      const long long depth = p.Integer("max_depth").value_or(-1);
      if (depth < -1) Fail(el, Format("max_depth ", depth, " must be >= -1"));
      out_.settings.max_depth = static_cast<int>(depth);
      p.Integer("rr_depth");  // Russian roulette: noise only
      out_.settings.hide_emitters = p.Boolean("hide_emitters");
    } else if (type == "direct") {
      out_.settings.max_depth = 2;  // emitters seen directly + one bounce (§9)
      for (const char* n : {"shading_samples", "emitter_samples", "bsdf_samples"}) p.Integer(n);
      out_.settings.hide_emitters = p.Boolean("hide_emitters");
    } else {
      Fail(el, Format("integrator type '", type, "' is not in the subset (path, direct)"));
    }
    if (!p.children().empty()) Fail(p.children()[0], "nested integrators are not in the subset");
    p.Finish();
    out_.settings.integrator = type;
  }

  fs::path main_file_;
  const MitsubaImportOptions& options_;
  std::map<std::string, std::string> params_;
  std::vector<fs::path> search_;
  std::vector<std::unique_ptr<XMLDocument>> docs_;
  std::vector<std::unique_ptr<fs::path>> files_;
  std::map<std::string, XMLElement*> ids_;
  std::vector<XMLElement*> top_;
  std::set<const XMLElement*> referenced_;
  std::map<const XMLElement*, Reflectance> bsdfs_;
  LoadedScene out_;
};

}  // namespace

LoadedScene ImportMitsubaXml(const fs::path& path, const MitsubaImportOptions& options) {
  return Importer(path, options).Run();
}

}  // namespace genscene::render
