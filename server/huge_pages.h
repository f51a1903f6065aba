// tcmalloc's page heap grown in transparent huge pages (huge_pages.cc says why).
#pragma once

namespace gvd {

// Call once, before the threads start. Linked only where the server allocates with tcmalloc.
void UseHugePages();

}  // namespace gvd
