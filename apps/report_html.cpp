#include "apps/report_html.h"

#include <cmark-gfm-core-extensions.h>
#include <cmark-gfm.h>

#include <memory>

#include "core/check.h"
#include "core/file_util.h"

namespace genscene::apps {
namespace {

namespace fs = std::filesystem;

constexpr const char* kStyle = R"(
body { font-family: sans-serif; max-width: 1100px; margin: 1em auto; padding: 0 1em;
       color: #222; line-height: 1.4; overflow-wrap: break-word; }
pre { overflow-x: auto; }
table { border-collapse: collapse; margin: 0.5em 0; display: block; overflow-x: auto; }
th, td { border: 1px solid #bbb; padding: 0.2em 0.6em; text-align: left; }
th { background: #eee; }
img { max-width: 100%; }
code { background: #f3f3f3; padding: 0 0.2em; overflow-wrap: anywhere; }
#view3d { width: 100%; height: 520px; background: #202020; }
#view3d-status { color: #555; font-size: 90%; }
)";

// The viewer: the .glb (base64 in GENSCENE_GLB) parsed by GLTFLoader, its point lights turned
// into markers (a model with dozens of lights would exhaust WebGL's uniforms), lit by a
// hemisphere light and a light that moves with the camera, seen first from its first camera; a
// button (or the page's address ending in #observed) shows the observed colour, the unlit
// material variant, instead of the albedo.
constexpr const char* kViewer = R"(
(function () {
  var status = document.getElementById('view3d-status');
  function fail(message) {
    document.body.setAttribute('data-model', 'error');
    status.textContent = '3D view unavailable: ' + message;
    console.error('genscene report: ' + message);
  }
  window.addEventListener('error', function (e) { fail(e.message); });
  try {
    var box = document.getElementById('view3d');
    var width = box.clientWidth, height = box.clientHeight;
    var renderer;
    try {
      renderer = new THREE.WebGLRenderer({antialias: true, preserveDrawingBuffer: true});
    } catch (e) {
      fail('this browser has no WebGL (' + e.message + ')');
      return;
    }
    renderer.setSize(width, height);
    renderer.setClearColor(0x202020);
    renderer.outputEncoding = THREE.sRGBEncoding;
    box.appendChild(renderer.domElement);
    var scene = new THREE.Scene();
    scene.add(new THREE.HemisphereLight(0xffffff, 0x606060, 0.8));
    var camera = new THREE.PerspectiveCamera(60, width / height, 0.01, 1000);
    var headlight = new THREE.DirectionalLight(0xffffff, 0.5);
    camera.add(headlight);
    scene.add(camera);
    var bytes = Uint8Array.from(atob(GENSCENE_GLB), function (c) { return c.charCodeAt(0); });
    new THREE.GLTFLoader().parse(bytes.buffer, '', function (gltf) {
      var model = gltf.scene;
      model.updateMatrixWorld(true);
      var bounds = new THREE.Box3().setFromObject(model);
      var centre = bounds.getCenter(new THREE.Vector3());
      var radius = Math.max(bounds.getSize(new THREE.Vector3()).length() / 2, 1e-3);
      var lights = [];
      model.traverse(function (o) { if (o.isLight) lights.push(o); });
      var marker = new THREE.SphereBufferGeometry(0.006 * radius, 8, 6);
      var glyphs = [];
      var glow = new THREE.MeshBasicMaterial({color: 0xffd040});
      lights.forEach(function (light) {
        var at = light.getWorldPosition(new THREE.Vector3());
        light.parent.remove(light);
        var m = new THREE.Mesh(marker, glow);
        m.position.copy(at);
        glyphs.push(m);
        scene.add(m);
      });
      // Non-power-of-two atlases keep their resolution (WebGL 1 resizes mipmapped ones).
      var meshes = [];
      model.traverse(function (o) {
        if (!o.isMesh) return;
        meshes.push(o);
        if (o.material.map) {
          o.material.map.generateMipmaps = false;
          o.material.map.minFilter = THREE.LinearFilter;
        }
      });
      scene.add(model);
      var controls = new THREE.OrbitControls(camera, renderer.domElement);
      if (gltf.cameras.length > 0) {
        var first = gltf.cameras[0];
        first.updateMatrixWorld(true);
        first.matrixWorld.decompose(camera.position, camera.quaternion, new THREE.Vector3());
        camera.fov = Math.min(Math.max(first.fov * 1.2, 30), 90);
        camera.up.set(0, 1, 0).applyQuaternion(camera.quaternion);
        var ahead = new THREE.Vector3(0, 0, -1).applyQuaternion(camera.quaternion);
        var depth = Math.max(centre.clone().sub(camera.position).dot(ahead), 0.1 * radius);
        controls.target.copy(camera.position).addScaledVector(ahead, depth);
      } else {
        camera.position.copy(centre).add(new THREE.Vector3(0, 0.6 * radius, 2.2 * radius));
        controls.target.copy(centre);
      }
      camera.near = 0.001 * radius;
      camera.far = 100 * radius;
      camera.updateProjectionMatrix();
      controls.update();
      function draw() { renderer.render(scene, camera); }
      controls.addEventListener('change', draw);
      draw();
      // The observed colour: the unlit material that KHR_materials_variants selects.
      var materials = gltf.parser.json.materials || [];
      var observed = -1;
      materials.forEach(function (m, i) {
        if (m.extensions && m.extensions.KHR_materials_unlit) observed = i;
      });
      var toggle = document.getElementById('view3d-colour');
      if (observed >= 0 && meshes.length > 0) {
        var albedo = meshes.map(function (o) { return o.material; });
        gltf.parser.getDependency('material', observed).then(function (unlit) {
          if (unlit.map) {
            unlit.map.generateMipmaps = false;
            unlit.map.minFilter = THREE.LinearFilter;
          }
          var showing = 'albedo';
          toggle.style.display = '';
          toggle.onclick = function () {
            showing = showing === 'albedo' ? 'observed' : 'albedo';
            meshes.forEach(function (o, i) {
              o.material = showing === 'albedo' ? albedo[i] : unlit;
            });
            toggle.textContent = showing === 'albedo' ? 'Show the observed colour'
                                                      : 'Show the albedo';
            draw();
          };
          if (window.location.hash === '#observed') toggle.onclick();
        });
      }
      var markers = document.getElementById('view3d-lights');
      markers.onclick = function () {
        glyphs.forEach(function (g) { g.visible = !g.visible; });
        draw();
      };
      status.textContent = 'Drag to orbit, scroll to zoom. ' + lights.length +
          ' light sources shown as yellow markers.';
      document.body.setAttribute('data-model', 'loaded');
    }, function (e) { fail('model.glb: ' + (e && e.message ? e.message : e)); });
  } catch (e) {
    fail(e.message);
  }
})();
)";

// What the 3D view needs, from libjs-three: the library and the two classic example scripts.
const std::vector<std::pair<const char*, const char*>> kThreeFiles = {
    {"three.min.js", "three.min.js"},
    {"examples/js/loaders/GLTFLoader.js", "GLTFLoader.js"},
    {"examples/js/controls/OrbitControls.js", "OrbitControls.js"},
};

std::string HtmlEscape(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '<') {
      out += "&lt;";
    } else if (c == '>') {
      out += "&gt;";
    } else if (c == '&') {
      out += "&amp;";
    } else {
      out += c;
    }
  }
  return out;
}

// Copies three.js next to the page and writes the model script; returns why it could not.
std::string PrepareViewer(const fs::path& dir, const ReportHtmlInputs& inputs) {
  if (inputs.glb.empty() || !fs::exists(inputs.glb)) return "no export/model.glb in the workspace";
  for (const auto& [from, to] : kThreeFiles) {
    if (!fs::exists(inputs.three_dir / from)) {
      return Format((inputs.three_dir / from).string(),
                    " is missing (install Debian's libjs-three for the 3D view)");
    }
  }
  fs::create_directories(dir / "three");
  for (const auto& [from, to] : kThreeFiles) {
    fs::copy_file(inputs.three_dir / from, dir / "three" / to,
                  fs::copy_options::overwrite_existing);
  }
  WriteTextFileAtomically(dir / "model_glb.js",
                          "var GENSCENE_GLB = \"" + Base64(ReadTextFile(inputs.glb)) + "\";\n");
  return "";
}

}  // namespace

std::string Base64(const std::string& bytes) {
  static const char* kDigits = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  for (size_t i = 0; i < bytes.size(); i += 3) {
    const size_t n = std::min<size_t>(3, bytes.size() - i);
    uint32_t v = 0;
    for (size_t k = 0; k < 3; ++k) {
      v = (v << 8) | (k < n ? static_cast<unsigned char>(bytes[i + k]) : 0u);
    }
    for (size_t k = 0; k < 4; ++k) {
      out += k <= n ? kDigits[(v >> (18 - 6 * k)) & 63] : '=';
    }
  }
  return out;
}

std::string MarkdownToHtml(const std::string& markdown) {
  cmark_gfm_core_extensions_ensure_registered();
  const std::unique_ptr<cmark_parser, decltype(&cmark_parser_free)> parser(
      cmark_parser_new(CMARK_OPT_DEFAULT), &cmark_parser_free);
  cmark_syntax_extension* table = cmark_find_syntax_extension("table");
  if (!parser || !table) throw Error("cmark-gfm: no parser with the table extension");
  cmark_parser_attach_syntax_extension(parser.get(), table);
  cmark_parser_feed(parser.get(), markdown.data(), markdown.size());
  const std::unique_ptr<cmark_node, decltype(&cmark_node_free)> document(
      cmark_parser_finish(parser.get()), &cmark_node_free);
  if (!document) throw Error("cmark-gfm could not parse the report");
  char* html = cmark_render_html(document.get(), CMARK_OPT_DEFAULT,
                                 cmark_parser_get_syntax_extensions(parser.get()));
  if (!html) throw Error("cmark-gfm could not render the report");
  std::string out(html);
  cmark_get_default_mem_allocator()->free(html);
  return out;
}

std::vector<std::string> WriteReportHtml(const fs::path& dir, const ReportHtmlInputs& inputs) {
  std::vector<std::string> warnings;
  const std::string no_view = PrepareViewer(dir, inputs);
  std::string page =
      "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
      "<title>genscene report</title>\n<style>" +
      std::string(kStyle) + "</style>\n</head>\n<body>\n";
  std::string view = "<h2>The model in 3D</h2>\n";
  if (no_view.empty()) {
    view +=
        "<div id=\"view3d\"></div>\n<p><button id=\"view3d-colour\" style=\"display: none\">"
        "Show the observed colour</button> <button id=\"view3d-lights\">Light markers on / off"
        "</button> <span id=\"view3d-status\">Loading export/model.glb ...</span></p>\n"
        "<script src=\"three/three.min.js\"></script>\n"
        "<script src=\"three/GLTFLoader.js\"></script>\n"
        "<script src=\"three/OrbitControls.js\"></script>\n"
        "<script src=\"model_glb.js\"></script>\n<script>" +
        std::string(kViewer) + "</script>\n";
  } else {
    view += "<p id=\"view3d-status\">No 3D view: " + HtmlEscape(no_view) + ".</p>\n";
    warnings.push_back("report.html without the 3D view: " + no_view);
  }
  // The view goes under the report's title.
  std::string body = MarkdownToHtml(inputs.markdown);
  const size_t title_end = body.find("</h1>\n");
  const size_t at = title_end == std::string::npos ? 0 : title_end + 6;
  page += body.substr(0, at) + view + body.substr(at);
  page += "</body>\n</html>\n";
  WriteTextFileAtomically(dir / "report.html", page);
  return warnings;
}

}  // namespace genscene::apps
