// tcmalloc's memory from the system in transparent huge pages (2 MiB) where the kernel gives
// them on request (/sys/kernel/mm/transparent_hugepage/enabled: madvise or always). A page
// heap that grows by 2 MiB at a time and asks for huge pages takes one page fault where 4 KiB
// pages take 512: on a virtual machine whose first touch of a page costs some 12 µs, a load
// of 100,000 points took 14-26 k faults (tests/bench/README.md, "The allocator").
#include "server/huge_pages.h"

#include <gperftools/malloc_extension.h>
#include <sys/mman.h>

#include <algorithm>

namespace gvd {
namespace {

constexpr size_t kHugePage = size_t{2} << 20;

class HugePageAllocator final : public SysAllocator {
 public:
  explicit HugePageAllocator(SysAllocator* system) : system_(system) {}
  void* Alloc(size_t size, size_t* actual_size, size_t alignment) override {
    const size_t rounded = (size + kHugePage - 1) / kHugePage * kHugePage;
    void* p = system_->Alloc(rounded, actual_size, std::max(alignment, kHugePage));
    if (p == nullptr) return system_->Alloc(size, actual_size, alignment);
    madvise(p, *actual_size, MADV_HUGEPAGE);  // advice: refused, the memory is as it was
    return p;
  }

 private:
  SysAllocator* const system_;
};

}  // namespace

void UseHugePages() {
  MallocExtension* malloc = MallocExtension::instance();
  SysAllocator* system = malloc->GetSystemAllocator();
  if (system == nullptr) return;  // not tcmalloc
  static HugePageAllocator allocator(system);
  malloc->SetSystemAllocator(&allocator);
}

}  // namespace gvd
