// Walk and fly: a click on the canvas gives the viewer the keyboard and mouse (pointer lock where
// the browser grants it; otherwise the mouse looks while a button is held, or by plain moves after
// the click). W/A/S/D move, Space jumps, G toggles flying, the mouse looks. Walking keeps the eye
// 1.6 m over the loaded rooms' floors (a ray down through their patch meshes, collision.js); where
// no floor is found the player holds still, never falls through.

export const EYE_HEIGHT = 1.6;
export const WALK_SPEED = 4.0; // m/s (scheduler.js's walking speed)
export const FLY_SPEED = 8.0;
const GRAVITY = 9.81;
const JUMP_SPEED = 4.2;
const STEP_UP = 0.7; // metres the feet may rise in one move (a steeper rise is a wall)
const LOOK = 0.0025; // radians a pixel of mouse move

export class Controls {
  constructor(canvas, pose, collide) {
    this.canvas = canvas;
    this.pose = pose; // {x, y, z, yaw, pitch}: mutated
    this.collide = collide; // (x, y, z) -> floor height under the point (within reach) or null
    // (x, y, z) -> whether the point is in the loaded rooms' space; flying stops at its edge (the
    // player never flies out into rock, where no room holds it). Null: anywhere.
    this.inside = null;
    this.keys = new Set();
    this.fly = false;
    this.vy = 0;
    this.grounded = false;
    this.active = false;
    this.dragging = false;
    this.onKey = null; // (code) for one-shot keys (L)
    canvas.tabIndex = 0;
    canvas.addEventListener("click", () => {
      this.active = true;
      canvas.focus();
      if (canvas.requestPointerLock) {
        try {
          const r = canvas.requestPointerLock();
          if (r && r.catch) r.catch(() => {});
        } catch {
          /* not granted: plain mouse moves */
        }
      }
    });
    canvas.addEventListener("mousedown", () => {
      this.dragging = true;
      this.active = true;
    });
    window.addEventListener("mouseup", () => (this.dragging = false));
    window.addEventListener("mousemove", (e) => {
      const locked = document.pointerLockElement === canvas;
      if (!locked && !this.dragging) return;
      this.look(e.movementX || 0, e.movementY || 0);
    });
    window.addEventListener("keydown", (e) => {
      if (!this.active && document.activeElement !== canvas) return;
      if (["KeyW", "KeyA", "KeyS", "KeyD", "Space", "ArrowUp", "ArrowDown", "ArrowLeft", "ArrowRight"].includes(e.code)) e.preventDefault();
      if (!e.repeat) {
        if (e.code === "KeyG") this.fly = !this.fly;
        if (e.code === "Space" && !this.fly && this.grounded) {
          this.vy = JUMP_SPEED;
          this.grounded = false;
        }
        this.onKey?.(e.code);
      }
      this.keys.add(e.code);
    });
    window.addEventListener("keyup", (e) => this.keys.delete(e.code));
    window.addEventListener("blur", () => this.keys.clear());
  }

  look(dx, dy) {
    this.pose.yaw += dx * LOOK;
    this.pose.pitch = Math.max(-1.55, Math.min(1.55, this.pose.pitch - dy * LOOK));
  }

  speed() {
    return this.fly ? FLY_SPEED : WALK_SPEED;
  }

  // Moves the pose by dt seconds of input (in steps of 50 ms at most, so that a slow frame, as
  // under software WebGL, still walks at walking speed). Returns whether it moved.
  update(dt) {
    let left = Math.min(Math.max(dt, 0), 1.0);
    let moved = false;
    while (left > 1e-6) {
      const h = Math.min(left, 0.05);
      moved = this.step(h) || moved;
      left -= h;
    }
    return moved;
  }

  step(dt) {
    const p = this.pose;
    const k = this.keys;
    const fwd = (k.has("KeyW") || k.has("ArrowUp") ? 1 : 0) - (k.has("KeyS") || k.has("ArrowDown") ? 1 : 0);
    const side = (k.has("KeyD") ? 1 : 0) - (k.has("KeyA") ? 1 : 0);
    const turn = (k.has("ArrowRight") ? 1 : 0) - (k.has("ArrowLeft") ? 1 : 0);
    if (turn) p.yaw += turn * 1.8 * dt;
    const sy = Math.sin(p.yaw), cy = Math.cos(p.yaw);
    const before = [p.x, p.y, p.z];
    if (this.fly) {
      const cp = Math.cos(p.pitch), sp = Math.sin(p.pitch);
      const f = [sy * cp, sp, -cy * cp];
      const r = [cy, 0, sy];
      const v = this.speed() * dt;
      const nx = p.x + (f[0] * fwd + r[0] * side) * v;
      const ny = p.y + (f[1] * fwd) * v + ((k.has("Space") ? 1 : 0) - (k.has("ShiftLeft") ? 1 : 0)) * v;
      const nz = p.z + (f[2] * fwd + r[2] * side) * v;
      // Out of the rooms' space only from inside it: a player already outside (a link into
      // rock, rooms not loaded yet) may move back in.
      if (!this.inside || this.inside(nx, ny, nz) || !this.inside(p.x, p.y, p.z)) {
        p.x = nx;
        p.y = ny;
        p.z = nz;
      }
      this.vy = 0;
      return p.x !== before[0] || p.y !== before[1] || p.z !== before[2];
    }
    // Walking: horizontal move, accepted only where a floor lies under the new place within a
    // step of the feet; then gravity onto that floor.
    const len = Math.hypot(fwd, side) || 1;
    const v = (this.speed() * dt) / len;
    const nx = p.x + (sy * fwd + cy * side) * v;
    const nz = p.z + (-cy * fwd + sy * side) * v;
    const feet = p.y - EYE_HEIGHT;
    const here = this.collide(p.x, p.y + 0.2, p.z);
    if (nx !== p.x || nz !== p.z) {
      const there = this.collide(nx, feet + STEP_UP + EYE_HEIGHT * 0.5, nz);
      if (there !== null && there <= feet + STEP_UP) {
        p.x = nx;
        p.z = nz;
      }
    }
    const floor = this.collide(p.x, p.y + 0.2, p.z) ?? here;
    if (floor === null) {
      // No floor known under the player (rooms not loaded yet): hold.
      this.vy = 0;
      this.grounded = false;
      return p.x !== before[0] || p.z !== before[2];
    }
    this.vy -= GRAVITY * dt;
    p.y += this.vy * dt;
    if (p.y - EYE_HEIGHT <= floor) {
      p.y = floor + EYE_HEIGHT;
      this.vy = 0;
      this.grounded = true;
    } else {
      this.grounded = false;
    }
    return p.x !== before[0] || p.y !== before[1] || p.z !== before[2];
  }
}
