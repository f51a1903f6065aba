// Limits that keep one request or scene from exhausting the server. Each has a flag.
#pragma once

#include <cstddef>
#include <cstdint>

namespace gvd {

struct ServerLimits {
  uint32_t max_side_px = 8192;               // width_px and height_px
  uint64_t max_scene_pixels = 8192ull * 8192; // width_px * height_px
  size_t max_scenes = 1000;
  size_t max_sites_per_scene = 1'000'000;
  size_t max_sites_per_request = 100'000;
  size_t max_points_per_query = 1'000'000;
  size_t max_vertices_per_site = 100'000;    // polyline points, polygon vertices
  uint64_t max_voxels_per_scene = 1ull << 26; // width_px * height_px * depth_px of a 3D scene
  size_t max_triangles_per_mesh = 1'000'000;
  size_t max_site_id_bytes = 256;
  size_t max_scene_id_chars = 128;
  uint32_t max_page_size = 10'000;
  int max_message_bytes = 256 << 20;         // gRPC receive and send
  size_t analysis_threads = 2;               // workers for boundaries, neighbours, planning...
  size_t max_queued_analyses = 64;           // calls waiting for a worker
  size_t max_queued_writes = 1024;           // writes waiting for a commit thread
  uint64_t max_memory = UINT64_MAX;          // bytes the scenes may hold (gvd-server sets it)
};

}  // namespace gvd
