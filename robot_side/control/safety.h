// The robot station's safety pieces, one file each: the command watchdog,
// the collision guard of the base, the keep-out check of arm targets and the
// store of seen voxels it checks 3D points against. Include the one you use;
// this header gathers them for code that uses all.
#pragma once

#include "robot_side/control/arm_keep_out.h"
#include "robot_side/control/collision_guard.h"
#include "robot_side/control/seen_voxels.h"
#include "robot_side/control/watchdog.h"
