// The workspace folder (DESIGN.md §2): every stage reads its inputs from and writes its outputs
// to one folder, so that any stage can be re-run, inspected or fed by hand. Outputs are written
// atomically (file_util.h), so an existing output is a complete one; `genscene run` skips a stage
// whose outputs exist and were made from the same inputs and options (StageFingerprints()).
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace genscene {

class Workspace {
 public:
  // Creates the folder when missing; throws Error when it exists as a file or cannot be made.
  explicit Workspace(std::filesystem::path root);

  const std::filesystem::path& root() const { return root_; }

  // The files of the stage contracts.
  std::filesystem::path Input() const {
    return root_ / "input";
  }  // synthesised or converted sequence
  // The frames `genscene run` recorded from a live camera; the chain runs on this recording.
  std::filesystem::path LiveRecording() const { return root_ / "capture.oni"; }
  std::filesystem::path Trajectory() const { return root_ / "trajectory.txt"; }
  std::filesystem::path Tsdf() const { return root_ / "tsdf.gsv"; }
  std::filesystem::path Keyframes() const { return root_ / "keyframes"; }
  // Frames kept out of the model (fusion's holdout), posed, to judge the model on.
  std::filesystem::path HeldOut() const { return root_ / "holdout"; }
  std::filesystem::path Mesh() const { return root_ / "mesh.ply"; }
  std::filesystem::path Texture() const { return root_ / "texture.mcol"; }
  std::filesystem::path TexturePly() const { return root_ / "texture.ply"; }
  std::filesystem::path Albedo() const { return root_ / "albedo.mcol"; }
  std::filesystem::path AlbedoPly() const { return root_ / "albedo.ply"; }
  std::filesystem::path Lights() const { return root_ / "lights.json"; }
  // The albedo the lights stage estimated jointly with the lights (Mesh Colors, and as vertex
  // colours of the subdivided mesh), written when the joint estimate kept a step.
  std::filesystem::path JointAlbedo() const { return root_ / "albedo_joint.mcol"; }
  std::filesystem::path JointAlbedoPly() const { return root_ / "albedo_joint.ply"; }
  // The model's albedo: the joint albedo when the lights stage has written it, else albedo.mcol.
  std::filesystem::path ModelAlbedo() const {
    return std::filesystem::exists(JointAlbedo()) ? JointAlbedo() : Albedo();
  }
  std::filesystem::path RefinedMesh() const { return root_ / "mesh_refined.ply"; }
  // The model's mesh: the refined one when refinement has written it, else mesh.ply.
  std::filesystem::path ModelMesh() const {
    return std::filesystem::exists(RefinedMesh()) ? RefinedMesh() : Mesh();
  }
  std::filesystem::path Log() const { return root_ / "genscene.log"; }
  // Each stage's report (options, figures) and its folder of images.
  std::filesystem::path SequenceJson() const { return root_ / "sequence.json"; }
  std::filesystem::path FusionJson() const { return root_ / "fusion.json"; }
  std::filesystem::path TextureJson() const { return root_ / "texture.json"; }
  std::filesystem::path AlbedoJson() const { return root_ / "albedo.json"; }
  std::filesystem::path LightsDir() const { return root_ / "lights"; }
  std::filesystem::path RefineDir() const { return root_ / "refine"; }
  std::filesystem::path RefineReport() const { return RefineDir() / "report.json"; }
  std::filesystem::path ExportDir() const { return root_ / "export"; }
  std::filesystem::path EvaluationDir() const { return root_ / "evaluation"; }
  std::filesystem::path EvaluationJson() const { return EvaluationDir() / "evaluation.json"; }
  std::filesystem::path HeldOutJson() const { return EvaluationDir() / "holdout.json"; }
  // The run's rows (stage, seconds, memory, figures), for `genscene report`.
  std::filesystem::path SummaryJson() const { return root_ / "summary.json"; }
  // What each stage of the chain was made from: {"stage": fingerprint of its inputs and options}.
  std::filesystem::path StageFingerprints() const { return root_ / "stages.json"; }
  std::filesystem::path Report() const { return root_ / "report"; }

 private:
  std::filesystem::path root_;
};

}  // namespace genscene
