// render/testing.h - switches the tests set on a renderer; not installed, not for applications.
//
// hold_async_work: where the async queue is the frame's own (lavapipe), each async submission (the
// device path's lagged cone bands) is held on the host until a submission or a host wait needs it, so
// that it runs as late as a GPU's other queue may run it: on lavapipe, which runs one queue in order,
// a wait left out then changes what a frame computes, and the tests see it.
#pragma once

#include "render/render.h"

namespace displace::render::testing {

void hold_async_work(Renderer& renderer, bool hold = true);

}  // namespace displace::render::testing
